//! `fitstation live`: the station screen on two cameras, running the real station
//! processing ([`StationProcessor`], the same as `fitstation replay --ui`).
//!
//! - Cameras through [`crate::capture`] (cargo feature `camera`); a missing or
//!   unplugged camera is shown on screen and retried, never a panic.
//! - The first [`CAMERA_SETTLE_FRAMES`] pairs only settle the cameras' automatic
//!   exposure and white balance ([`SettleFirst`]); then the station learns the empty
//!   backdrop, and exposure and white balance are locked (otherwise a shopper entering
//!   would make auto-exposure change the backdrop's look).
//! - Without a usable `station.yaml` the screen shows the frames and asks for the
//!   operator's calibration wizard; a solved calibration is put to use from the
//!   operator panel (the processor factory), as is learning the backdrop again.
//!
//! Units: frames in pixels, measurements in millimetres, board sizes in millimetres at
//! the command line.

use super::calib_wizard::WizardSettings;
#[cfg(feature = "camera")]
use super::AppOptions;
use super::ProcessorFactory;
use crate::calibrate::board::{BoardSpec, Target};
use crate::camera::StationCalibration;
use crate::pipeline::{FitSnapshot, FramePair, FrameProcessor, Phase};
use crate::station::{StationOptions, StationProcessor};
use std::path::PathBuf;

/// Frame pairs given to the cameras' automatic exposure before the backdrop is learnt
/// (about a second at 30 fps).
pub const CAMERA_SETTLE_FRAMES: u64 = 30;

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
    /// The station calibration; without a readable one the screen shows the frames
    /// and the operator calibrates with the wizard.
    #[arg(long, default_value = "station.yaml")]
    pub calibration: PathBuf,
    /// Calibration board: inner corners COLSxROWS.
    #[arg(long, default_value = "9x6")]
    pub board: String,
    /// Side of one printed square (or the circle spacing), millimetres.
    #[arg(long, default_value_t = 75.0)]
    pub square_mm: f64,
    /// The board is a circle grid instead of a chessboard.
    #[arg(long)]
    pub circles: bool,
    /// Height of the placement board's lowest inner-corner row above the floor, mm.
    #[arg(long, default_value_t = 600.0)]
    pub board_height_mm: f64,
    /// Stature typed by the operator, millimetres (otherwise measured from the views).
    #[arg(long)]
    pub stature_mm: Option<f64>,
    /// Start with the operator tools open.
    #[arg(long)]
    pub operator: bool,
    /// Where the operator's recordings go.
    #[arg(long, default_value = "recordings")]
    pub record_dir: PathBuf,
    /// Save a screenshot of the window (PNG) after --exit-after-frames frames.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Close after this many screen frames.
    #[arg(long)]
    pub exit_after_frames: Option<u64>,
}

/// Passes the first `settle` pairs through as "learning" snapshots with the frames (the
/// screen shows the cameras while their exposure settles), then hands every pair to
/// `inner`.
pub struct SettleFirst<P> {
    inner: P,
    settle: u64,
    seen: u64,
}

impl<P: FrameProcessor> SettleFirst<P> {
    pub fn new(inner: P, settle: u64) -> Self {
        SettleFirst {
            inner,
            settle,
            seen: 0,
        }
    }
}

impl<P: FrameProcessor> FrameProcessor for SettleFirst<P> {
    fn process(&mut self, pair: &FramePair) -> FitSnapshot {
        if self.seen < self.settle {
            self.seen += 1;
            let mut s = FitSnapshot::empty(pair.index, Phase::LearningBackdrop);
            s.messages.push(format!(
                "Cameras settling ({}/{}): keep the scene empty",
                self.seen, self.settle
            ));
            s.front_frame = Some(pair.front.clone());
            s.side_frame = Some(pair.side.clone());
            return s;
        }
        self.inner.process(pair)
    }
    fn reset_subject(&mut self) {
        self.inner.reset_subject();
    }
}

/// Shows the frames with a message and never fits (no calibration yet).
pub struct FramesWithMessage(pub String);

impl FrameProcessor for FramesWithMessage {
    fn process(&mut self, pair: &FramePair) -> FitSnapshot {
        let mut s = FitSnapshot::empty(pair.index, Phase::LearningBackdrop);
        s.messages.push(self.0.clone());
        s.front_frame = Some(pair.front.clone());
        s.side_frame = Some(pair.side.clone());
        s
    }
}

/// A factory of station processors (the shape library loaded once), each waiting
/// `settle` pairs before learning the backdrop.
pub fn station_factory(opts: StationOptions, settle: u64) -> anyhow::Result<ProcessorFactory> {
    let library = crate::station::default_library()?;
    Ok(Box::new(move |cal: &StationCalibration| {
        StationProcessor::new(cal.clone(), library.clone(), opts.clone())
            .map(|p| Box::new(SettleFirst::new(p, settle)) as Box<dyn FrameProcessor>)
            .map_err(|e| e.to_string())
    }))
}

/// The first processor: the station when a calibration is known, else frames only.
pub fn first_processor(
    factory: &ProcessorFactory,
    calibration: Option<&StationCalibration>,
) -> Box<dyn FrameProcessor> {
    match calibration {
        Some(cal) => match factory(cal) {
            Ok(p) => p,
            Err(e) => Box::new(FramesWithMessage(format!(
                "The station cannot start with this calibration ({e}): recalibrate in operator mode"
            ))),
        },
        None => Box::new(FramesWithMessage(
            "No calibration: open Operator > Calibration and run the wizard, then use the calibration".into(),
        )),
    }
}

/// Reads the station calibration if there is a usable one (a missing or broken file is
/// said, not fatal).
pub fn load_calibration(path: &std::path::Path) -> Option<StationCalibration> {
    if !path.exists() {
        eprintln!(
            "note: no {}: starting without a calibration (Operator > Calibration)",
            path.display()
        );
        return None;
    }
    match StationCalibration::load(path) {
        Ok(c) => Some(c),
        Err(e) => {
            eprintln!("warning: {e}: starting without a calibration (Operator > Calibration)");
            None
        }
    }
}

/// The wizard's settings from the command line.
pub fn wizard_settings(args: &LiveArgs) -> anyhow::Result<WizardSettings> {
    let board = BoardSpec::parse(&args.board, args.square_mm).map_err(anyhow::Error::msg)?;
    Ok(WizardSettings {
        board,
        target: if args.circles {
            Target::Circles
        } else {
            Target::Chessboard
        },
        board_height_m: args.board_height_mm / 1e3,
        out: args.calibration.clone(),
    })
}

pub fn run_live_cli(args: LiveArgs) -> anyhow::Result<()> {
    #[cfg(feature = "camera")]
    {
        use crate::capture::{CameraPairSource, CaptureConfig, PixelFormat};
        let format = match args.format.to_ascii_lowercase().as_str() {
            "mjpeg" | "mjpg" => PixelFormat::Mjpeg,
            "yuyv" => PixelFormat::Yuyv,
            other => anyhow::bail!("unknown --format {other}: use mjpeg or yuyv"),
        };
        let wizard = wizard_settings(&args)?;
        let mut station = StationOptions::default();
        if let Some(mm) = args.stature_mm {
            if !(500.0..=2600.0).contains(&mm) {
                anyhow::bail!("--stature-mm {mm} is not a plausible stature (500 to 2600 mm)");
            }
            station.stature_m = Some(mm / 1e3);
        }
        let calibration = load_calibration(&args.calibration);
        let factory = station_factory(station, CAMERA_SETTLE_FRAMES)?;
        let processor = first_processor(&factory, calibration.as_ref());
        let config = CaptureConfig {
            front: args.front.clone(),
            side: args.side.clone(),
            width: args.width,
            height: args.height,
            fps: args.fps,
            format,
            ..Default::default()
        };
        let source = CameraPairSource::open_cameras(config, calibration);
        let locks = source.controls();
        let opts = AppOptions {
            title: "fitstation live".into(),
            operator: args.operator || calibration_missing(&args.calibration),
            exit_after_frames: args.exit_after_frames.or(args
                .screenshot
                .as_ref()
                .map(|_| super::demo_ui::DEFAULT_SCREENSHOT_FRAMES)),
            screenshot: args.screenshot.clone(),
            on_backdrop_learned: Some(Box::new(move || locks.request_lock())),
            wizard,
            processor_factory: Some(factory),
            record_dir: args.record_dir.clone(),
            ..Default::default()
        };
        let summary = super::run(Box::new(source), processor, opts)?;
        print!("{summary}");
        Ok(())
    }
    #[cfg(not(feature = "camera"))]
    {
        let _ = args;
        anyhow::bail!("this fitstation was built without cameras: rebuild with `cargo build --release --features camera` (needs Debian's libclang-dev)")
    }
}

/// True when the calibration file is missing or unreadable (the operator tools open).
#[cfg_attr(not(feature = "camera"), allow(dead_code))]
fn calibration_missing(path: &std::path::Path) -> bool {
    StationCalibration::load(path).is_err()
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Fixed;
    impl FrameProcessor for Fixed {
        fn process(&mut self, pair: &FramePair) -> FitSnapshot {
            FitSnapshot::empty(pair.index, Phase::WaitingForSubject)
        }
    }

    fn pair(i: u64) -> FramePair {
        FramePair {
            index: i,
            timestamp_s: i as f64 / 30.0,
            front: image::RgbImage::new(4, 4).into(),
            side: image::RgbImage::new(4, 4).into(),
        }
    }

    #[test]
    fn settling_frames_are_shown_not_processed() {
        let mut p = SettleFirst::new(Fixed, 3);
        for i in 0..3 {
            let s = p.process(&pair(i));
            assert_eq!(s.phase, Phase::LearningBackdrop);
            assert!(s.front_frame.is_some() && s.side_frame.is_some());
        }
        assert_eq!(p.process(&pair(3)).phase, Phase::WaitingForSubject);
    }

    #[test]
    fn no_calibration_shows_frames_and_asks_for_the_wizard() {
        let factory: ProcessorFactory = Box::new(|_| Err("unused".into()));
        let mut p = first_processor(&factory, None);
        let s = p.process(&pair(0));
        assert_eq!(s.phase, Phase::LearningBackdrop);
        assert!(s.messages[0].contains("No calibration"), "{:?}", s.messages);
        assert!(s.front_frame.is_some());
        let cal = crate::app::demo::demo_calibration();
        let mut p = first_processor(&factory, Some(&cal));
        assert!(p.process(&pair(0)).messages[0].contains("cannot start"));
        assert!(load_calibration(std::path::Path::new("/nonexistent/station.yaml")).is_none());
    }
}
