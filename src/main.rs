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
    /// Landmarks, joints and frame verdicts from one front and one side image.
    Landmarks(fitstation::landmarks::cli::LandmarksArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Version => println!("fitstation {}", env!("CARGO_PKG_VERSION")),
        Command::Landmarks(args) => fitstation::landmarks::cli::run(args)?,
    }
    Ok(())
}
