//! The `fitstation` command line.
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
    /// Print the version.
    Version,
    /// Body templates and the shape library (import, prepare, bodies).
    Templates(fitstation::body::TemplatesArgs),
    /// Measure a body mesh: stature and tape girths (ISO 8559-1).
    Measure(fitstation::measure::MeasureArgs),
    /// Render a synthetic two-camera recording with its ground truth beside it.
    Synth(fitstation::synth::SynthArgs),
    /// Render a deterministic evaluation set of synthetic subjects.
    SynthSet(fitstation::synth::SynthSetArgs),
    /// Score fits of recordings against their ground truth.
    Eval(fitstation::eval::EvalArgs),
    /// Time a pipeline stage on realistic inputs.
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Mean value deformation: encoding, paper-style and fast decoding, warm refit, libigl peer.
    Deform(fitstation::deform::bench::BenchArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Version => println!("fitstation {}", env!("CARGO_PKG_VERSION")),
        Command::Templates(args) => fitstation::body::run(args)?,
        Command::Measure(args) => fitstation::measure::run(args)?,
        Command::Synth(args) => fitstation::synth::run(args)?,
        Command::SynthSet(args) => fitstation::synth::run_set(args)?,
        Command::Eval(args) => fitstation::eval::run(args)?,
        Command::Bench {
            what: BenchCommand::Deform(args),
        } => fitstation::deform::bench::run(args)?,
    }
    Ok(())
}
