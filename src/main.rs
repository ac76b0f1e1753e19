//! The `fitstation` command line.
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "fitstation", version, about = "Two-camera capture-and-fit body measurement station")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the version.
    Version,
    /// Calibrate the two cameras (lens, then position at the mark) or check a station.yaml.
    Calibrate(fitstation::calibrate::cli::CalibrateArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Version => println!("fitstation {}", env!("CARGO_PKG_VERSION")),
        Command::Calibrate(args) => fitstation::calibrate::cli::run(args)?,
    }
    Ok(())
}
