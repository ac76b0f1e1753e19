//! `fitstation replay` and `fitstation fit`: run the station on a recording or on a pair
//! of stills and write `avatar.obj` + `report.json` (`../shared/spec/formats.md`).

use crate::camera::StationCalibration;
use crate::capture::inject::FaultInjector;
use crate::deform::DecoderKind;
use crate::fit::correspond::Variant;
use crate::fit::deformer::DeformerKind;
use crate::pipeline::timing::TimingStats;
use crate::pipeline::{FitSnapshot, FramePair, FrameProcessor, FrameSource, Phase, SourceError};
use crate::recording::{Recording, RecordingWriter};
use crate::station::output::write_fit_outputs;
use crate::station::{
    default_library, StationOptions, StationProcessor, ViewSet, MEASUREMENT_KEYS,
};
mod eval;
mod fit;
pub use eval::{run_eval, EvalCmd};
pub use fit::{run_fit, FitArgs};

use anyhow::{bail, Context};
use std::path::{Path, PathBuf};

/// Options shared by `replay` and `fit`.
#[derive(Debug, Clone, clap::Args)]
pub struct FitCliOptions {
    /// Stature typed by the operator, millimetres (otherwise measured from the views).
    #[arg(long)]
    pub stature_mm: Option<f64>,
    /// Correspondence: the paper's slice extremes or perspective rims.
    #[arg(long, value_enum, default_value = "perspective-rim")]
    pub correspondence: Variant,
    /// Mean value decoder.
    #[arg(long, value_enum, default_value = "fast")]
    pub decoder: DecoderChoice,
    /// Print the report as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Do not run the learned pose model on the side view (arms told from the trunk by
    /// shape alone).
    #[arg(long)]
    pub no_person_model: bool,
    /// Views to fit from: both cameras, or the front camera alone (depths from the shape
    /// library, a wider ±; give --stature-mm for the best stature).
    #[arg(long, value_enum, default_value = "both")]
    pub views: ViewSet,
    /// Deformer of the fit: mean value (the paper's) or Laplacian.
    #[arg(long, value_enum, default_value = "mvc")]
    pub deformer: DeformerKind,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DecoderChoice {
    /// Sparse Cholesky Gauss-Newton.
    Fast,
    /// The paper's iteration (slow; for comparison).
    Paper,
}

impl FitCliOptions {
    fn station_options(&self) -> anyhow::Result<StationOptions> {
        let mut o = StationOptions::default();
        if let Some(mm) = self.stature_mm {
            if !(500.0..=2600.0).contains(&mm) {
                bail!("--stature-mm {mm} is not a plausible stature (500 to 2600 mm)");
            }
            o.stature_m = Some(mm / 1000.0);
        }
        o.fit.variant = self.correspondence;
        o.person_model = !self.no_person_model;
        o.views = self.views;
        o.fit.deformer = self.deformer;
        o.fit.decoder = match self.decoder {
            DecoderChoice::Fast => DecoderKind::FastGaussNewton,
            DecoderChoice::Paper => DecoderKind::PaperIterative,
        };
        Ok(o)
    }
}

/// `fitstation replay REC --out DIR`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReplayArgs {
    /// Recording folder (station.yaml + front/ side/ frames or front.mp4 side.mp4).
    pub recording: PathBuf,
    /// Where avatar.obj and report.json go.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Stop after this many frame pairs.
    #[arg(long)]
    pub max_frames: Option<usize>,
    /// Show the station screen (views, avatar, measurements) while replaying.
    #[arg(long)]
    pub ui: bool,
    /// With --ui: save a screenshot of the window after --exit-after-frames frames.
    #[arg(long, requires = "ui")]
    pub screenshot: Option<PathBuf>,
    /// With --ui: close the window after this many screen frames.
    #[arg(long, requires = "ui")]
    pub exit_after_frames: Option<u64>,
    /// With --ui: start with the operator tools open.
    #[arg(long, requires = "ui")]
    pub operator: bool,
    /// With --ui, for window tests: play scripted input (`app::ui_script`).
    #[arg(long, requires = "ui", hide = true)]
    pub ui_script: Option<PathBuf>,
    /// With --ui, for window tests: write what the hand edits did here at exit.
    #[arg(long, requires = "ui", hide = true)]
    pub ui_edits_out: Option<PathBuf>,
    /// Inject faults into the frames, e.g. 'drop-side@4:2,stall@8:1.5' (see --help).
    #[arg(long, value_name = "SPEC", long_help = crate::capture::inject::SPEC_HELP)]
    pub inject: Option<String>,
    /// Also record the frame pairs the station is given into this new recording folder
    /// (recording.yaml and station.yaml first, then each frame written whole, so a cut
    /// recording replays up to the cut).
    #[arg(long, conflicts_with = "ui")]
    pub record: Option<PathBuf>,
    /// Frame format of --record.
    #[arg(long, value_enum, default_value = "png", requires = "record")]
    pub record_format: crate::recording::FrameFormat,
    /// Write the station's final silhouettes of every frame pair after the backdrop
    /// (`front/NNNNNN.png`, `side/NNNNNN.png`) into this folder, to look at what was fitted.
    #[arg(long, value_name = "DIR")]
    pub masks_out: Option<PathBuf>,
    #[command(flatten)]
    pub fit: FitCliOptions,
}

/// A frame source that also appends every pair it gives to a new recording
/// (`replay --record`); a failed write is said once and recording stops, the replay
/// goes on.
pub struct RecordingTee<'a> {
    inner: &'a mut dyn FrameSource,
    writer: Option<RecordingWriter>,
    dir: PathBuf,
}

impl<'a> RecordingTee<'a> {
    /// Starts a recording in `dir` (which must not hold one) with `inner`'s
    /// calibration and frame rate.
    ///
    /// # Errors
    /// `dir` holds a recording, is a file, or cannot be written.
    pub fn start(
        inner: &'a mut dyn FrameSource,
        dir: &Path,
        format: crate::recording::FrameFormat,
        stature_m: Option<f64>,
    ) -> anyhow::Result<Self> {
        if dir.join(crate::recording::STATION_FILE).exists() {
            bail!(
                "{} already holds a recording (station.yaml exists): choose a new folder for --record",
                dir.display()
            );
        }
        let calib = inner
            .calibration()
            .context("the source has no calibration to record with")?
            .clone();
        let meta = crate::recording::RecordingMeta {
            fps: inner.fps().unwrap_or(crate::recording::DEFAULT_FPS),
            stature_m,
            notes: Some(format!(
                "recorded by fitstation replay from {}",
                inner.describe()
            )),
            date: None,
        };
        let writer = RecordingWriter::with_meta(dir, &calib, format, meta)
            .with_context(|| format!("cannot record to {}", dir.display()))?;
        Ok(RecordingTee {
            inner,
            writer: Some(writer),
            dir: dir.to_path_buf(),
        })
    }

    /// Closes the recording (video index, recording.yaml); returns the pairs written.
    ///
    /// # Errors
    /// The closing writes failed.
    pub fn finish(mut self) -> anyhow::Result<usize> {
        let Some(w) = self.writer.take() else {
            return Ok(0);
        };
        let n = w.len();
        w.finish()
            .with_context(|| format!("cannot finish the recording {}", self.dir.display()))?;
        Ok(n)
    }
}

impl FrameSource for RecordingTee<'_> {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        let r = self.inner.next_pair();
        if let (Ok(Some(pair)), Some(w)) = (&r, self.writer.as_mut()) {
            if let Err(e) = w.push_pair(&pair.front, &pair.side) {
                eprintln!(
                    "warning: recording to {} stopped after {} frame pairs: {e}",
                    self.dir.display(),
                    w.len()
                );
                self.writer = None;
            }
        }
        r
    }
    fn calibration(&self) -> Option<&StationCalibration> {
        self.inner.calibration()
    }
    fn fps(&self) -> Option<f64> {
        self.inner.fps()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

/// Frame pairs from a recording, in order; unreadable frames are skipped and said.
pub struct RecordingSource {
    rec: Recording,
    next: usize,
    /// Pairs given so far (indices and timestamps keep rising when looping).
    given: u64,
    /// Start again at the first frame after the last (the station screen's replay).
    pub looping: bool,
    name: String,
}

impl RecordingSource {
    pub fn open(dir: &Path) -> anyhow::Result<Self> {
        let rec = Recording::open(dir)
            .with_context(|| format!("cannot open recording {}", dir.display()))?;
        Ok(RecordingSource {
            rec,
            next: 0,
            given: 0,
            looping: false,
            name: format!("recording {}", dir.display()),
        })
    }
    pub fn recording(&self) -> &Recording {
        &self.rec
    }
}

impl FrameSource for RecordingSource {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        if self.next >= self.rec.len() {
            if !self.looping || self.rec.is_empty() {
                return Ok(None);
            }
            self.next = 0;
        }
        let k = self.next;
        self.next += 1;
        let index = self.given;
        self.given += 1;
        let fps = self.rec.metadata().fps.max(1e-3);
        match self.rec.frame_pair(k) {
            Ok((front, side)) => Ok(Some(FramePair {
                index,
                timestamp_s: index as f64 / fps,
                front: front.into(),
                side: side.into(),
            })),
            Err(e) => Err(SourceError::Skipped(format!("frame {k}: {e}"))),
        }
    }
    fn calibration(&self) -> Option<&StationCalibration> {
        Some(self.rec.calibration())
    }
    fn fps(&self) -> Option<f64> {
        Some(self.rec.metadata().fps)
    }
    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// The outcome of running the station over a source.
pub struct RunSummary {
    pub report: serde_json::Value,
    pub avatar: Option<crate::mesh::TriMesh>,
    pub last: Option<FitSnapshot>,
}

/// Runs a processor over every frame of a source (no frame dropped: offline replay).
pub fn run_offline(
    source: &mut dyn FrameSource,
    proc_: &mut StationProcessor,
    max_frames: Option<usize>,
    progress: bool,
) -> RunSummary {
    let mut log = RunLog::default();
    let mut n = 0usize;
    let style = crate::io::progress::ProgressStyle::for_stderr();
    let mut shown_phase = None;
    loop {
        if max_frames.is_some_and(|m| n >= m) {
            break;
        }
        let pair = match source.next_pair() {
            Ok(Some(p)) => p,
            Ok(None) => break,
            Err(SourceError::Fatal(e)) => {
                log.messages.push(e);
                break;
            }
            Err(e) => {
                log.faults.source(&e.to_string());
                if !log.messages.contains(&e.to_string()) {
                    log.messages.push(e.to_string());
                }
                proc_.counts.total += 1;
                n += 1;
                continue;
            }
        };
        n += 1;
        let snap = proc_.process(&pair);
        for f in &snap.faults {
            log.faults.station(pair.index, pair.timestamp_s, f);
        }
        if progress {
            show_frame_progress(style, pair.index, snap.phase, &mut shown_phase);
        }
        log.record(&pair, snap);
    }
    if progress && style == crate::io::progress::ProgressStyle::InPlace {
        eprintln!();
    }
    let RunLog {
        mut timings,
        mut messages,
        faults,
        series,
        last,
    } = log;
    let (meas, stab, unc, uncertain) = measurement_maps(proc_);
    let steps: serde_json::Map<String, serde_json::Value> = proc_
        .max_steps()
        .into_iter()
        .map(|(k, v)| (k, round1(v).into()))
        .collect();
    let settled_steps = settled_steps(&series);
    let landmarks: serde_json::Map<String, serde_json::Value> = proc_
        .landmarks()
        .into_iter()
        .map(|(k, p)| (k, point_json(p)))
        .collect();
    let body_landmarks = fitted_body_landmarks(proc_, &mut timings, &mut messages);
    // The views the reported values were fitted from (`["front"]`: the side view was
    // missing or not used, and the uncertainties are the one-view ones).
    let views: Vec<&str> = proc_.views().map_or(&[][..], |v| v.names()).to_vec();
    let report = serde_json::json!({
        "measurements_mm": meas,
        "views": views,
        "deformer": proc_.options().fit.deformer,
        "frames": proc_.counts,
        "timings_ms": timings.to_json(),
        "stability_mm": stab,
        "uncertainty_mm": unc,
        "uncertain": uncertain,
        "max_frame_step_mm": steps,
        "settled_step_mm": settled_steps,
        "landmarks": landmarks,
        "body_landmarks": body_landmarks,
        "fit": proc_.last_fit,
        "messages": messages,
        "faults": faults.entries,
        "series": series,
    });
    RunSummary {
        report,
        avatar: proc_.avatar().map(|a| (*a).clone()),
        last,
    }
}

/// What a run gathers frame by frame for its report.
#[derive(Default)]
struct RunLog {
    timings: TimingStats,
    messages: Vec<String>,
    faults: FaultLog,
    series: Vec<serde_json::Value>,
    last: Option<FitSnapshot>,
}

impl RunLog {
    /// Takes in one frame pair's snapshot: its stage timings (after the backdrop was
    /// learned), its new messages, and its measurements while fitting.
    fn record(&mut self, pair: &FramePair, snap: FitSnapshot) {
        if snap.phase != Phase::LearningBackdrop {
            self.timings.add_all(&snap.timings_ms);
        }
        for m in &snap.messages {
            if !m.starts_with("Learning") && !self.messages.contains(m) {
                self.messages.push(m.clone());
            }
        }
        if matches!(snap.phase, Phase::Fitting | Phase::Settled) {
            let mut row = serde_json::Map::new();
            row.insert("frame".into(), pair.index.into());
            for mv in &snap.measurements {
                row.insert(mv.name.clone(), round1(mv.value_mm).into());
            }
            self.series.push(serde_json::Value::Object(row));
        }
        self.last = Some(snap);
    }
}

/// report.json's measurement maps: values, stability, uncertainty, and the names of
/// the uncertain ones.
type MeasurementMaps = (
    serde_json::Map<String, serde_json::Value>,
    serde_json::Map<String, serde_json::Value>,
    serde_json::Map<String, serde_json::Value>,
    Vec<String>,
);

/// The final measurements as report.json's maps: values, stability, uncertainty (where
/// known), and the names of the uncertain ones.
fn measurement_maps(proc_: &StationProcessor) -> MeasurementMaps {
    let mut meas = serde_json::Map::new();
    let mut stab = serde_json::Map::new();
    let mut unc = serde_json::Map::new();
    let mut uncertain = Vec::new();
    for mv in proc_.measurements() {
        meas.insert(mv.name.clone(), round1(mv.value_mm).into());
        if mv.stability_mm.is_finite() {
            stab.insert(mv.name.clone(), round1(mv.stability_mm).into());
        }
        if mv.uncertainty_mm.is_finite() {
            unc.insert(mv.name.clone(), round1(mv.uncertainty_mm).into());
        }
        if mv.uncertain {
            uncertain.push(mv.name.clone());
        }
    }
    (meas, stab, unc, uncertain)
}

/// The fitted body's own landmarks, by the template's definitions (horizontal sections
/// of the avatar): once per run, not per frame, its time in `timings`.
fn fitted_body_landmarks(
    proc_: &StationProcessor,
    timings: &mut TimingStats,
    messages: &mut Vec<String>,
) -> serde_json::Map<String, serde_json::Value> {
    let mut body_landmarks = serde_json::Map::new();
    if let Some(avatar) = proc_.avatar() {
        let t0 = std::time::Instant::now();
        match crate::body::surface_landmarks(&avatar) {
            Ok(l) => {
                for (k, p) in l.named() {
                    body_landmarks.insert(k.into(), point_json(p));
                }
            }
            Err(e) => messages.push(format!("the fitted body's landmarks: {e}")),
        }
        timings.add(ONCE_PER_RUN_STAGE, t0.elapsed().as_secs_f64() * 1e3);
    }
    body_landmarks
}

/// The faults of a run as `report.json` `faults` lists them and stderr logs them: the
/// station's (one per pair, with its frame and time) and the source's errors (a run of
/// the same error is one entry with its count of pairs).
#[derive(Default)]
struct FaultLog {
    entries: Vec<serde_json::Value>,
    /// The source error of the last entry while it repeats.
    repeating: Option<String>,
}

impl FaultLog {
    /// Logs a fault the station found on pair `frame` at `time_s`.
    fn station(&mut self, frame: u64, time_s: f64, fault: &str) {
        self.repeating = None;
        eprintln!("\rfault: frame {frame} ({time_s:.2} s): {fault}");
        self.entries.push(serde_json::json!({
            "frame": frame, "time_s": round4(time_s), "fault": fault,
        }));
    }

    /// Logs an error of the source (a lost camera, a skipped frame).
    fn source(&mut self, fault: &str) {
        if self.repeating.as_deref() == Some(fault) {
            if let Some(n) = self.entries.last_mut().and_then(|e| e.get_mut("pairs")) {
                *n = (n.as_u64().unwrap_or(0) + 1).into();
            }
            return;
        }
        eprintln!("\rfault: source: {fault}");
        self.repeating = Some(fault.to_string());
        self.entries
            .push(serde_json::json!({ "source": fault, "pairs": 1 }));
    }
}

/// Shows replay progress: every frame redrawn in place on a terminal; otherwise one
/// plain line each time the phase changes (a log gets no carriage returns).
fn show_frame_progress(
    style: crate::io::progress::ProgressStyle,
    index: u64,
    phase: Phase,
    shown: &mut Option<Phase>,
) {
    use crate::io::progress::{show, ProgressStyle};
    match style {
        ProgressStyle::InPlace => show(
            style,
            &format!("frame {index:>4}  {:<20}", format!("{phase:?}")),
            false,
        ),
        ProgressStyle::Lines if *shown != Some(phase) => {
            show(style, &format!("frame {index:>4}  {phase:?}"), false)
        }
        ProgressStyle::Lines => {}
    }
    *shown = Some(phase);
}

/// The stage of `timings_ms` timed once per run, not per frame pair: the fitted body's
/// landmarks.
const ONCE_PER_RUN_STAGE: &str = "body_landmarks";

/// A station-frame point as report.json writes it (metres, 0.1 mm).
fn point_json(p: glam::DVec3) -> serde_json::Value {
    serde_json::json!({"x": round4(p.x), "y": round4(p.y), "z": round4(p.z)})
}

/// Largest change of each shown (smoothed) measurement between consecutive fitted frames
/// once its window is full ([`crate::pipeline::smooth::WINDOW`] fits): what a shopper
/// sees the value do after it has settled. Empty before that many fits.
fn settled_steps(series: &[serde_json::Value]) -> serde_json::Map<String, serde_json::Value> {
    let mut out = serde_json::Map::new();
    let rows: Vec<&serde_json::Map<String, serde_json::Value>> = series
        .iter()
        .filter_map(|r| r.as_object())
        .skip(crate::pipeline::smooth::WINDOW.saturating_sub(1))
        .collect();
    for key in MEASUREMENT_KEYS {
        let values: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.get(key).and_then(|v| v.as_f64()))
            .collect();
        if values.len() < 2 {
            continue;
        }
        let step = values
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        out.insert(key.to_string(), round1(step).into());
    }
    out
}

fn round1(v: f64) -> f64 {
    (v * 10.0).round() / 10.0
}
fn round4(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

/// `fitstation replay`.
pub fn run_replay(args: &ReplayArgs) -> anyhow::Result<()> {
    let faults = args
        .inject
        .as_deref()
        .map(crate::capture::inject::parse_spec)
        .transpose()?;
    #[cfg(not(feature = "gui"))]
    if args.ui {
        anyhow::bail!("this fitstation was built without the station screen (cargo feature `gui`)");
    }
    check_outputs(args.out.as_deref(), args.record.as_deref())?;
    #[cfg_attr(not(feature = "gui"), allow(unused_mut))]
    let mut source = RecordingSource::open(&args.recording)?;
    for w in source.recording().warnings() {
        eprintln!("warning: {w}");
    }
    let calib = source.recording().calibration().clone();
    let mut opts = args.fit.station_options()?;
    if opts.stature_m.is_none() {
        opts.stature_m = source.recording().metadata().stature_m;
    }
    opts.masks_out = args.masks_out.clone();
    #[cfg_attr(not(feature = "gui"), allow(unused_variables))]
    let backdrop_frames = opts.backdrop_frames;
    let mut proc_ = StationProcessor::new(calib, default_library()?, opts)?;
    #[cfg(feature = "gui")]
    if args.ui {
        // On screen the recording plays in a loop at its own frame rate; frames the
        // station cannot keep up with are dropped, as with live cameras.
        // The backdrop is learned from the recording's first (empty) frames before the
        // screen starts: on screen, frames the station cannot keep up with are dropped,
        // and a learning phase that skipped into the subject frames would learn the
        // subject as backdrop.
        for _ in 0..backdrop_frames {
            match source.next_pair() {
                Ok(Some(pair)) => {
                    proc_.process(&pair);
                }
                Ok(None) => break,
                Err(e) => eprintln!("warning: {e}"),
            }
        }
        source.looping = true;
        let app_opts = crate::app::AppOptions {
            title: format!("fitstation: replay {}", args.recording.display()),
            screenshot: args.screenshot.clone(),
            exit_after_frames: args.exit_after_frames,
            operator: args.operator,
            ui_script: match &args.ui_script {
                Some(p) => crate::app::ui_script::read_script(p)?,
                None => Vec::new(),
            },
            edits_out: args.ui_edits_out.clone(),
            ..crate::app::AppOptions::default()
        };
        let source: Box<dyn FrameSource> = match faults {
            Some(f) => Box::new(
                FaultInjector::new(Box::new(source), f)
                    .real_time(true)
                    .log_to_stderr(true),
            ),
            None => Box::new(source),
        };
        let summary = crate::app::run(source, Box::new(proc_), app_opts)?;
        eprint!("{summary}");
        return Ok(());
    }
    let stature_m = source.recording().metadata().stature_m;
    let mut source: Box<dyn FrameSource> = match faults {
        Some(f) => Box::new(FaultInjector::new(Box::new(source), f).log_to_stderr(true)),
        None => Box::new(source),
    };
    let summary = match &args.record {
        None => run_offline(source.as_mut(), &mut proc_, args.max_frames, !args.fit.json),
        Some(dir) => {
            let mut tee = RecordingTee::start(source.as_mut(), dir, args.record_format, stature_m)?;
            let summary = run_offline(&mut tee, &mut proc_, args.max_frames, !args.fit.json);
            let n = tee.finish()?;
            eprintln!("recorded {n} frame pairs to {}", dir.display());
            summary
        }
    };
    finish(summary, args.out.as_deref(), args.fit.json)
}

/// Says before any work when an output folder is an existing file.
fn check_outputs(out: Option<&Path>, record: Option<&Path>) -> anyhow::Result<()> {
    for (flag, dir) in [("--out", out), ("--record", record)] {
        if let Some(d) = dir {
            crate::io::atomic::check_dir(d).map_err(|e| anyhow::anyhow!("{flag}: {e}"))?;
        }
    }
    Ok(())
}

fn finish(summary: RunSummary, out: Option<&Path>, json: bool) -> anyhow::Result<()> {
    let Some(avatar) = summary.avatar else {
        let msgs = summary.report["messages"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|m| m.as_str())
                    .collect::<Vec<_>>()
                    .join("; ")
            })
            .unwrap_or_default();
        let msgs = if msgs.is_empty() {
            "the recording ends before anybody steps in after the empty scene".to_string()
        } else {
            msgs
        };
        bail!(
            "no frame could be fitted ({} frames, {} with a subject): {msgs}",
            summary.report["frames"]["total"],
            summary.report["frames"]["with_subject"]
        );
    };
    if let Some(out) = out {
        write_fit_outputs(out, &avatar, &summary.report)?;
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&summary.report)?);
    } else {
        print_table(&summary.report);
        if let Some(out) = out {
            println!(
                "wrote {}/avatar.obj and {}/report.json",
                out.display(),
                out.display()
            );
        }
    }
    Ok(())
}

/// The person network's cost spread over the frame pairs showing the subject (its
/// [`crate::station::NETWORK_STAGES`] run on some pairs only); `None` when it never ran or nobody was
/// seen.
fn network_cost_line(
    timings: &serde_json::Map<String, serde_json::Value>,
    with_subject: Option<u64>,
) -> Option<String> {
    let pairs = with_subject.filter(|&n| n > 0)? as f64;
    let net = timings.get(crate::station::PERSON_MASK_STAGE)?;
    let spent = |stage: &str| {
        timings.get(stage).map_or(0.0, |v| {
            v["mean"].as_f64().unwrap_or(0.0) * v["count"].as_f64().unwrap_or(0.0)
        })
    };
    let runs = net["count"].as_u64()?;
    let total: f64 = crate::station::NETWORK_STAGES
        .iter()
        .map(|s| spent(s))
        .sum();
    Some(format!(
        "person network: ran on {runs} of {pairs} pairs with the subject, {:.2} ms a pair on \
         average with its second segmentation and the side view's arms ({:.2} ms median, \
         {:.2} p95 where it ran)",
        total / pairs,
        net["median"].as_f64().unwrap_or(0.0),
        net["p95"].as_f64().unwrap_or(0.0),
    ))
}

fn print_table(report: &serde_json::Value) {
    println!("{:<20} {:>10} {:>12}", "measurement", "mm", "stability");
    for k in MEASUREMENT_KEYS {
        let v = report["measurements_mm"][k].as_f64();
        let s = report["stability_mm"][k].as_f64();
        match v {
            Some(v) => println!(
                "{:<20} {:>10.1} {:>12}",
                k,
                v,
                s.map(|s| format!("±{s:.1}")).unwrap_or_else(|| "-".into())
            ),
            None => println!("{k:<20} {:>10}", "-"),
        }
    }
    let f = &report["frames"];
    println!(
        "frames: {} total, {} with subject, {} fitted",
        f["total"], f["with_subject"], f["fitted"]
    );
    if let Some(t) = report["timings_ms"].as_object() {
        let ms = |v: &serde_json::Value| v["median"].as_f64().unwrap_or(0.0);
        let parts: Vec<String> = t
            .iter()
            .filter(|(k, _)| k.as_str() != ONCE_PER_RUN_STAGE)
            .map(|(k, v)| format!("{k} {:.2}", ms(v)))
            .collect();
        println!("median ms per frame pair: {}", parts.join(", "));
        if let Some(line) = network_cost_line(t, report["frames"]["with_subject"].as_u64()) {
            println!("{line}");
        }
        if let Some(v) = t.get(ONCE_PER_RUN_STAGE) {
            println!("once per run: {ONCE_PER_RUN_STAGE} {:.2} ms", ms(v));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_network_cost_is_spread_over_the_pairs_showing_the_subject() {
        let t = serde_json::json!({
            "silhouettes": {"median": 8.0, "p95": 9.0, "mean": 8.0, "count": 40},
            "person_mask": {"median": 100.0, "p95": 120.0, "mean": 105.0, "count": 5},
            "silhouettes_fused": {"median": 7.0, "p95": 8.0, "mean": 7.0, "count": 5},
            "side_limbs": {"median": 50.0, "p95": 50.0, "mean": 50.0, "count": 2},
        });
        let t = t.as_object().expect("object");
        let line = network_cost_line(t, Some(40)).expect("the network ran");
        // (5 * 105 + 5 * 7 + 2 * 50) / 40 = 16.5 ms a pair.
        assert!(line.contains("ran on 5 of 40 pairs"), "{line}");
        assert!(line.contains("16.50 ms a pair on average"), "{line}");
        assert!(line.contains("(100.00 ms median, 120.00 p95"), "{line}");
        assert_eq!(network_cost_line(t, Some(0)), None);
        let mut without = t.clone();
        without.remove("person_mask");
        assert_eq!(network_cost_line(&without, Some(40)), None);
    }
}
