//! The `fitstation` command line. Each subcommand's arguments and logic live in its
//! module; this file only dispatches.
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "fitstation",
    version,
    about = "Two-camera capture-and-fit body measurement station"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Replay a recording through the station; write avatar.obj and report.json.
    Replay(fitstation::cli::ReplayArgs),
    /// Fit one front and one side still; write avatar.obj and report.json.
    Fit(fitstation::cli::FitArgs),
    /// Landmarks, joints and frame verdicts from one front and one side image.
    Landmarks(fitstation::silhouette::cli::LandmarksArgs),
    /// Measure a body mesh: stature and tape girths (ISO 8559-1).
    Measure(fitstation::measure::MeasureArgs),
    /// Body templates and the shape library (import, prepare, bodies).
    Templates(fitstation::body::TemplatesArgs),
    /// Render a synthetic two-camera recording with its ground truth beside it.
    Synth(fitstation::synth::SynthArgs),
    /// Render a deterministic evaluation set of synthetic subjects.
    SynthSet(fitstation::synth::SynthSetArgs),
    /// Score fits of recordings against their ground truth.
    Eval(fitstation::cli::EvalCmd),
    /// Time a pipeline stage on realistic inputs.
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Print the version.
    Version,
    /// Calibrate the two cameras (lens, then position at the mark) or check a station.yaml.
    Calibrate(fitstation::calibrate::cli::CalibrateArgs),
    /// The station screen on a synthetic demo station (no cameras needed).
    #[cfg(feature = "gui")]
    DemoUi(fitstation::app::DemoUiArgs),
    /// The station screen on two live cameras (build with --features camera).
    #[cfg(feature = "gui")]
    Live(fitstation::app::LiveArgs),
    /// Loop a recording for a while (shoppers coming and going); check memory, threads, files, results.
    Soak(fitstation::soak::SoakArgs),
    /// Move a point of a fitted avatar by hand (the surface around follows), or undo it.
    Edit(fitstation::edit::cli::EditArgs),
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Mean value deformation: encoding, paper-style and fast decoding, warm refit, libigl peer.
    Deform(fitstation::deform::bench::BenchArgs),
}

/// A command line tool whose reader went away (`| head`) ends like any Unix tool: Rust
/// ignores SIGPIPE by default, which turns the closed pipe into a panic on the next print.
fn default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first in `main`, before any other thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Runs the command; an error is printed on one line ("Error: what: why"), without
/// repeating a cause its message already quotes (with its causes and backtrace when
/// RUST_BACKTRACE is set), and the exit code is 1.
fn main() -> std::process::ExitCode {
    default_sigpipe();
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0") => {
            eprintln!("Error: {e:?}");
            std::process::ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("Error: {}", one_line(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by ": ", each cause left out when the text so far
/// already contains it.
fn one_line(e: &anyhow::Error) -> String {
    let mut s = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if s.contains(&c) {
            continue;
        }
        if !s.is_empty() {
            s.push_str(": ");
        }
        s.push_str(&c);
    }
    s.replace('\n', " ")
}

/// Dispatches the subcommand.
fn run() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Replay(args) => fitstation::cli::run_replay(&args)?,
        Command::Fit(args) => fitstation::cli::run_fit(&args)?,
        Command::Landmarks(args) => fitstation::silhouette::cli::run(args)?,
        Command::Measure(args) => fitstation::measure::run(args)?,
        Command::Templates(args) => fitstation::body::run(args)?,
        Command::Synth(args) => fitstation::synth::run(args)?,
        Command::SynthSet(args) => fitstation::synth::run_set(args)?,
        Command::Eval(args) => fitstation::cli::run_eval(&args)?,
        Command::Bench {
            what: BenchCommand::Deform(args),
        } => fitstation::deform::bench::run(args)?,
        Command::Version => println!("fitstation {}", env!("CARGO_PKG_VERSION")),
        Command::Calibrate(args) => fitstation::calibrate::cli::run(args)?,
        #[cfg(feature = "gui")]
        Command::DemoUi(args) => fitstation::app::run_demo_cli(args)?,
        #[cfg(feature = "gui")]
        Command::Live(args) => fitstation::app::run_live_cli(args)?,
        Command::Soak(args) => fitstation::soak::run(&args)?,
        Command::Edit(args) => fitstation::edit::cli::run(&args)?,
    }
    Ok(())
}
