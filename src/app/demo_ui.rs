//! `fitstation demo-ui`: the screen on the synthetic demo station, or on a kiosk visit
//! scripted from a recording.

use super::*;

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
pub(crate) const DEFAULT_SCREENSHOT_FRAMES: u64 = 150;
