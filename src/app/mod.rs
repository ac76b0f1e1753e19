//! The station on screen (egui + wgpu through eframe): both camera views with the
//! silhouette contour, contour parts, landmarks and skeleton drawn over them; the avatar
//! in 3-D; the measurements with their stability; per-stage timings and frame rates; the
//! shopper's kiosk flow ([`flow`]) and the operator's tools (calibration hook,
//! recording, replay controls, exports).
//!
//! Entry point: [`run`] with any [`FrameSource`] and [`FrameProcessor`]; `fitstation
//! demo-ui` runs it on the synthetic [`demo`] station. Threads: see [`runner`]. The
//! screen owns the displayed snapshot, the textures and the flow; it uploads a camera
//! frame to the GPU only when a new one arrives, downscaled to at most
//! [`DISPLAY_MAX_PX`] on its longer side. Overlay coordinates are the cameras' pixels;
//! the avatar is in the station frame (metres).

pub mod avatar3d;
pub mod demo;
pub mod export;
pub mod flow;
pub mod operator;
pub mod record;
pub mod runner;

use crate::camera::StationCalibration;
use crate::pipeline::timing::TimingStats;
use crate::pipeline::{FitSnapshot, FrameProcessor, FrameSource, MeasurementValue, ViewOverlay};
use avatar3d::{AvatarCallback, AvatarResources, OrbitCamera, ViewPreset};
use egui::{Color32, Pos2, Rect, RichText, Stroke, TextureHandle, Vec2};
use flow::{FlowAction, FlowConfig, FlowInput, FlowState, KioskFlow};
use operator::{BoardDetections, CalibrationWizard, NoCalibrationWizard};
use runner::Runner;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Longest side of a camera frame as uploaded for display (pixels).
pub const DISPLAY_MAX_PX: u32 = 640;
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
    /// The calibration module's hook (a placeholder when `None`).
    pub calibration_wizard: Option<Box<dyn CalibrationWizard>>,
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
            calibration_wizard: None,
            on_backdrop_learned: None,
            record_dir: PathBuf::from("recordings"),
            export_dir: PathBuf::from("fitstation-export"),
            window_size: [1600.0, 900.0],
        }
    }
}

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
                .insert(AvatarResources::new(&rs.device, rs.target_format));
            let ctx = cc.egui_ctx.clone();
            let app = StationApp::new(
                source,
                processor,
                opts,
                Box::new(move || ctx.request_repaint()),
                summary,
            )?;
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
        for (s, med, p95) in &self.ui_timings {
            writeln!(f, "stage {s}: median {med:.2} ms, p95 {p95:.2} ms")?;
        }
        if let Some(p) = &self.screenshot {
            writeln!(f, "screenshot: {}", p.display())?;
        }
        Ok(())
    }
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

/// A camera view's texture and the size of the frame it came from.
struct ViewTexture {
    handle: TextureHandle,
    frame_size: [u32; 2],
    source: *const image::RgbImage,
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
    downscale_scratch: Vec<Color32>,
    avatar_generation: u64,
    avatar_ptr: *const crate::mesh::TriMesh,
    orbit: OrbitCamera,
    /// The operator zoomed by hand: stop fitting the avatar into the view.
    user_zoomed: bool,
    ui_meter: RateMeter,
    snap_meter: RateMeter,
    ui_stats: TimingStats,
    pipeline_stats: TimingStats,
    frames: u64,
    snapshots_shown: u64,
    screenshot_at: Option<u64>,
    auto_shot_requested: bool,
    screenshot_path: Option<PathBuf>,
    exit_after: Option<u64>,
    screenshot: ScreenshotState,
    layout: Layout,
    wizard: Box<dyn CalibrationWizard>,
    detections: BoardDetections,
    wizard_status: String,
    on_backdrop_learned: Option<Box<dyn FnMut() + Send>>,
    record_dir: String,
    export_dir: String,
    operator_log: VecDeque<String>,
    summary: Arc<Mutex<RunSummary>>,
    closing: bool,
}

/// Frames an automatic screenshot waits beyond its frame for a fitted avatar.
const SCREENSHOT_GRACE_FRAMES: u64 = 600;

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
            downscale_scratch: Vec::new(),
            avatar_generation: 0,
            avatar_ptr: std::ptr::null(),
            orbit: OrbitCamera::default(),
            user_zoomed: false,
            ui_meter: RateMeter::default(),
            snap_meter: RateMeter::default(),
            ui_stats: TimingStats::default(),
            pipeline_stats: TimingStats::default(),
            frames: 0,
            snapshots_shown: 0,
            screenshot_at: opts.screenshot.as_ref().and(exit_after),
            auto_shot_requested: false,
            screenshot_path: opts.screenshot,
            exit_after,
            screenshot: ScreenshotState::None,
            layout: Layout::default(),
            wizard: opts
                .calibration_wizard
                .unwrap_or_else(|| Box::new(NoCalibrationWizard)),
            detections: BoardDetections::default(),
            wizard_status: String::new(),
            on_backdrop_learned: opts.on_backdrop_learned,
            record_dir: opts.record_dir.display().to_string(),
            export_dir: opts.export_dir.display().to_string(),
            operator_log: VecDeque::new(),
            summary,
            closing: false,
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

    /// Takes the newest snapshot, feeds the flow, uploads changed frames.
    fn poll_snapshot(&mut self, ctx: &egui::Context) {
        let now = self.now_s();
        if let Some(snap) = self.runner.snapshots.try_take() {
            self.snapshots_shown += 1;
            self.snap_meter.tick(now);
            self.pipeline_stats.add_all(&snap.timings_ms);
            let was_learning = matches!(self.flow.state(), FlowState::LearningBackdrop);
            let action = self.flow.on_snapshot(&FlowInput::from_snapshot(&snap), now);
            if was_learning && !matches!(self.flow.state(), FlowState::LearningBackdrop) {
                if let Some(f) = self.on_backdrop_learned.as_mut() {
                    f();
                }
            }
            let t0 = Instant::now();
            if let Some(f) = &snap.front_frame {
                upload(
                    ctx,
                    &mut self.front_tex,
                    "front",
                    f,
                    &mut self.downscale_scratch,
                );
            }
            if let Some(f) = &snap.side_frame {
                upload(
                    ctx,
                    &mut self.side_tex,
                    "side",
                    f,
                    &mut self.downscale_scratch,
                );
            }
            self.ui_stats
                .add("upload", t0.elapsed().as_secs_f64() * 1e3);
            match &snap.avatar {
                Some(a) if Arc::as_ptr(a) != self.avatar_ptr => {
                    self.avatar_ptr = Arc::as_ptr(a);
                    self.avatar_generation += 1;
                }
                _ => {}
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
        self.avatar_ptr = std::ptr::null();
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
                    ui.label(
                        RichText::new(format!("{:.0} mm", m.value_mm))
                            .size(18.0)
                            .strong(),
                    );
                    ui.end_row();
                }
            });
            ui.separator();
        }
        ui.heading("Measurements");
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
                .num_columns(3)
                .show(ui, |ui| {
                    for m in &measurements {
                        ui.label(pretty_name(&m.name));
                        ui.label(RichText::new(format!("{:.1} mm", m.value_mm)).monospace());
                        stability_indicator(ui, m.stability_mm);
                        ui.end_row();
                    }
                });
        }
        ui.separator();
        ui.heading("Timings");
        if let Some(s) = &self.current {
            egui::Grid::new("timings").num_columns(3).show(ui, |ui| {
                ui.label("stage");
                ui.label("now");
                ui.label("median / p95");
                ui.end_row();
                let summary = self.pipeline_stats.summary();
                for (stage, ms) in &s.timings_ms {
                    ui.label(stage);
                    ui.label(format!("{ms:.2} ms"));
                    if let Some((_, sum)) = summary.iter().find(|(n, _)| n == stage) {
                        ui.label(format!("{:.2} / {:.2} ms", sum.median, sum.p95));
                    }
                    ui.end_row();
                }
                let threads = self.runner.controls.thread_stats().summary();
                let screen = self
                    .ui_stats
                    .summary()
                    .into_iter()
                    .map(|(n, v)| (format!("screen {n}"), v));
                for (stage, sum) in threads.into_iter().chain(screen) {
                    ui.label(stage);
                    ui.label("");
                    ui.label(format!("{:.2} / {:.2} ms", sum.median, sum.p95));
                    ui.end_row();
                }
            });
            ui.label(format!("frame {}  phase {:?}", s.frame_index, s.phase));
        }
    }

    fn operator_panel(&mut self, ui: &mut egui::Ui) {
        egui::ScrollArea::vertical().show(ui, |ui| {
            egui::CollapsingHeader::new("Calibration").default_open(true).show(ui, |ui| {
                ui.label(self.wizard.describe());
                ui.horizontal(|ui| {
                    if ui.button("Detect boards").clicked() {
                        let frames = self.current.as_ref().and_then(|s| Some((s.front_frame.clone()?, s.side_frame.clone()?)));
                        match frames {
                            Some((f, s)) => {
                                self.detections = self.wizard.detect(&f, &s);
                                self.wizard_status = format!(
                                    "{} board(s) in front, {} in side",
                                    self.detections.front.len(),
                                    self.detections.side.len()
                                );
                            }
                            None => self.wizard_status = "no frames yet".into(),
                        }
                    }
                    if ui.button("Add view").clicked() {
                        self.wizard_status = self.wizard.add_view();
                    }
                    if ui.button("Solve").clicked() {
                        match self.wizard.solve() {
                            Ok(cal) => {
                                self.wizard_status = "solved: station.yaml ready to save".into();
                                self.calibration = Some(cal);
                            }
                            Err(e) => self.wizard_status = e,
                        }
                    }
                });
                if !self.wizard_status.is_empty() {
                    ui.label(&self.wizard_status);
                }
                for (name, dets) in [("front", &self.detections.front), ("side", &self.detections.side)] {
                    for d in dets {
                        ui.label(format!("{name}: {} — {} corners {}", d.board, d.corners_px.len(), d.note));
                    }
                }
                ui.label(RichText::new("Station checks").strong());
                let sizes = self.front_tex.as_ref().zip(self.side_tex.as_ref()).map(|(f, s)| (f.frame_size, s.frame_size));
                let mut checks = operator::station_checks(self.calibration.as_ref(), sizes);
                checks.extend(self.wizard.station_checks(self.calibration.as_ref()));
                for c in checks {
                    let colour = if c.starts_with("PROBLEM") || c.starts_with("No calibration") {
                        Color32::from_rgb(255, 140, 0)
                    } else {
                        ui.visuals().text_color()
                    };
                    ui.label(RichText::new(c).color(colour).small());
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

    fn start_recording(&mut self) {
        let dir = PathBuf::from(&self.record_dir);
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
            let mut all = self.runner.controls.thread_stats().summary();
            all.extend(
                self.ui_stats
                    .summary()
                    .into_iter()
                    .map(|(n, v)| (format!("screen {n}"), v)),
            );
            s.ui_timings = all.into_iter().map(|(n, v)| (n, v.median, v.p95)).collect();
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
        let show_all = self.mode == Mode::Operator;
        let snap = self.current.as_ref();
        self.layout.front = draw_view(
            &painter,
            cols[0],
            "front",
            self.front_tex.as_ref(),
            snap.map(|s| &s.front),
            &self.detections.front,
            show_all,
        );
        self.layout.side = draw_view(
            &painter,
            cols[1],
            "side",
            self.side_tex.as_ref(),
            snap.map(|s| &s.side),
            &self.detections.side,
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
        let mesh = self.current.as_ref().and_then(|s| s.avatar.clone());
        if let Some(m) = &mesh {
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
        painter.add(eframe::egui_wgpu::Callback::new_paint_callback(
            avatar_rect,
            AvatarCallback {
                mesh,
                generation: self.avatar_generation,
                camera: self.orbit,
                size_points: [avatar_rect.width(), avatar_rect.height()],
            },
        ));
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
        let ctx = ui.ctx().clone();
        if ctx.input(|i| i.viewport().close_requested()) {
            self.closing = true;
        }
        self.frames += 1;
        let now = self.now_s();
        self.ui_meter.tick(now);
        self.poll_snapshot(&ctx);

        egui::Panel::top("top").show(ui, |ui| self.top_bar(ui));
        egui::Panel::bottom("kiosk").show(ui, |ui| self.kiosk_banner(ui));
        egui::Panel::right("measurements")
            .default_size(320.0)
            .show(ui, |ui| self.measurements_panel(ui));
        if self.mode == Mode::Operator {
            egui::Panel::left("operator")
                .default_size(340.0)
                .show(ui, |ui| self.operator_panel(ui));
        }
        // No panel fill behind the views: on a software renderer every covered pixel
        // costs (the window's clear colour is the background).
        egui::CentralPanel::no_frame().show(ui, |ui| self.views(ui));

        self.ui_stats.add("frame", t0.elapsed().as_secs_f64() * 1e3);
        // Screenshot and exit handling (CLI --screenshot / --exit-after-frames): the
        // automatic screenshot is due after N frames and waits (at most
        // SCREENSHOT_GRACE_FRAMES more) for a frame that shows a fitted avatar.
        let has_avatar = self.current.as_ref().is_some_and(|s| s.avatar.is_some());
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
        // Keep the countdown and timeouts moving without snapshots.
        ctx.request_repaint_after(std::time::Duration::from_millis(100));
    }

    fn on_exit(&mut self) {
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
    ui.horizontal(|ui| {
        let (r, _) = ui.allocate_exact_size(Vec2::splat(10.0), egui::Sense::hover());
        ui.painter().circle_filled(r.center(), 5.0, colour);
        ui.label(RichText::new(format!("±{spread_mm:.1} {word}")).small());
    });
}

/// Uploads `frame` into `slot` unless it is the frame already shown.
fn upload(
    ctx: &egui::Context,
    slot: &mut Option<ViewTexture>,
    name: &str,
    frame: &Arc<image::RgbImage>,
    scratch: &mut Vec<Color32>,
) {
    let ptr = Arc::as_ptr(frame);
    if slot.as_ref().is_some_and(|t| t.source == ptr) {
        return;
    }
    let img = downscale_for_display(frame, scratch);
    let frame_size = [frame.width(), frame.height()];
    match slot {
        Some(t) => {
            t.handle.set(img, egui::TextureOptions::LINEAR);
            t.frame_size = frame_size;
            t.source = ptr;
        }
        None => {
            let handle = ctx.load_texture(name, img, egui::TextureOptions::LINEAR);
            *slot = Some(ViewTexture {
                handle,
                frame_size,
                source: ptr,
            });
        }
    }
}

/// Box-filters a frame down by an integer factor so its longer side is at most
/// [`DISPLAY_MAX_PX`].
pub fn downscale_for_display(
    frame: &image::RgbImage,
    scratch: &mut Vec<Color32>,
) -> egui::ColorImage {
    let (w, h) = (frame.width() as usize, frame.height() as usize);
    let f = (w.max(h) as u32).div_ceil(DISPLAY_MAX_PX).max(1) as usize;
    let (ow, oh) = ((w / f).max(1), (h / f).max(1));
    scratch.clear();
    scratch.reserve(ow * oh);
    let raw = frame.as_raw();
    let n = (f * f) as u32;
    for oy in 0..oh {
        for ox in 0..ow {
            let mut acc = [0u32; 3];
            for dy in 0..f {
                let y = (oy * f + dy).min(h - 1);
                let row = y * w * 3;
                for dx in 0..f {
                    let x = (ox * f + dx).min(w - 1);
                    let i = row + x * 3;
                    acc[0] += raw[i] as u32;
                    acc[1] += raw[i + 1] as u32;
                    acc[2] += raw[i + 2] as u32;
                }
            }
            scratch.push(Color32::from_rgb(
                (acc[0] / n) as u8,
                (acc[1] / n) as u8,
                (acc[2] / n) as u8,
            ));
        }
    }
    egui::ColorImage::new([ow, oh], std::mem::take(scratch))
}

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
        painter.rect_filled(area, 4.0, Color32::from_gray(24));
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
    painter.image(
        tex.handle.id(),
        rect,
        Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
        Color32::WHITE,
    );
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
                for p in pts {
                    painter.circle_filled(to_screen(*p), 2.0, c);
                }
            }
            if o.avatar_outline.len() > 2 {
                let pts: Vec<Pos2> = o.avatar_outline.iter().map(|p| to_screen(*p)).collect();
                painter.add(egui::Shape::closed_line(
                    pts,
                    Stroke::new(1.0, AVATAR_OUTLINE_COLOUR),
                ));
            }
        }
        if o.contour.len() > 2 {
            let pts: Vec<Pos2> = o.contour.iter().map(|p| to_screen(*p)).collect();
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
    if let Some(d) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    rgb.save(path)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let px =
        |r: Option<Rect>| r.map(|r| [r.min.x * ppp, r.min.y * ppp, r.max.x * ppp, r.max.y * ppp]);
    let json = serde_json::json!({
        "width": w, "height": h, "pixels_per_point": ppp,
        "front": px(layout.front), "side": px(layout.side), "avatar": px(layout.avatar),
        "avatar_rgb": avatar3d::AVATAR_RGB,
    });
    let lp = layout_path(path);
    std::fs::write(&lp, serde_json::to_string_pretty(&json).unwrap_or_default())
        .map_err(|e| format!("{}: {e}", lp.display()))?;
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

/// Frames before a screenshot when only --screenshot is given.
const DEFAULT_SCREENSHOT_FRAMES: u64 = 150;

/// `fitstation live`: the screen on two cameras (needs the `camera` feature).
#[derive(clap::Args, Debug)]
pub struct LiveArgs {
    /// Front camera: index (0) or device path (/dev/video0).
    #[arg(long, default_value = "0")]
    pub front: String,
    /// Side camera: index or device path.
    #[arg(long, default_value = "1")]
    pub side: String,
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    #[arg(long, default_value_t = 30)]
    pub fps: u32,
    /// Pixel format: mjpeg or yuyv.
    #[arg(long, default_value = "mjpeg")]
    pub format: String,
    /// The station calibration (station.yaml); without it the screen warns.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Start with the operator tools open.
    #[arg(long)]
    pub operator: bool,
    /// Save a screenshot of the window (PNG) after --exit-after-frames frames.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Close after this many screen frames.
    #[arg(long)]
    pub exit_after_frames: Option<u64>,
}

pub fn run_live_cli(args: LiveArgs) -> anyhow::Result<()> {
    #[cfg(feature = "camera")]
    {
        use crate::capture::{CameraPairSource, CaptureConfig, PixelFormat};
        let calibration = match &args.calibration {
            Some(p) => Some(StationCalibration::load(p)?),
            None => None,
        };
        let format = match args.format.to_ascii_lowercase().as_str() {
            "mjpeg" | "mjpg" => PixelFormat::Mjpeg,
            "yuyv" => PixelFormat::Yuyv,
            other => anyhow::bail!("unknown --format {other}: use mjpeg or yuyv"),
        };
        let config = CaptureConfig {
            front: args.front.clone(),
            side: args.side.clone(),
            width: args.width,
            height: args.height,
            fps: args.fps,
            format,
            ..Default::default()
        };
        let source = CameraPairSource::open(config, calibration);
        let locks = source.controls();
        let opts = AppOptions {
            title: "fitstation live".into(),
            operator: args.operator,
            exit_after_frames: args
                .exit_after_frames
                .or(args.screenshot.as_ref().map(|_| DEFAULT_SCREENSHOT_FRAMES)),
            screenshot: args.screenshot.clone(),
            on_backdrop_learned: Some(Box::new(move || locks.request_lock())),
            ..Default::default()
        };
        let summary = run(Box::new(source), Box::new(demo::FramesOnlyProcessor), opts)?;
        print!("{summary}");
        Ok(())
    }
    #[cfg(not(feature = "camera"))]
    {
        let _ = args;
        anyhow::bail!("this fitstation was built without cameras: rebuild with `cargo build --release --features camera` (needs Debian's libclang-dev)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downscale_keeps_aspect_and_averages() {
        let mut img = image::RgbImage::new(1280, 720);
        for (x, _, p) in img.enumerate_pixels_mut() {
            *p = if x % 2 == 0 {
                image::Rgb([200, 0, 0])
            } else {
                image::Rgb([0, 0, 100])
            };
        }
        let mut scratch = Vec::new();
        let out = downscale_for_display(&img, &mut scratch);
        assert_eq!(out.size, [640, 360]);
        let c = out.pixels[1000];
        assert_eq!((c.r(), c.g(), c.b()), (100, 0, 50));
        let small = image::RgbImage::new(100, 50);
        assert_eq!(downscale_for_display(&small, &mut scratch).size, [100, 50]);
    }

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
    fn layout_path_sits_beside_the_screenshot() {
        assert_eq!(
            layout_path(Path::new("/tmp/a/shot.png")),
            PathBuf::from("/tmp/a/shot.layout.json")
        );
    }
}
