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
    /// The station screen on a synthetic demo station (no cameras needed).
    DemoUi(fitstation::app::DemoUiArgs),
    /// The station screen on two live cameras (build with --features camera).
    Live(fitstation::app::LiveArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Version => println!("fitstation {}", env!("CARGO_PKG_VERSION")),
        Command::DemoUi(args) => fitstation::app::run_demo_cli(args)?,
        Command::Live(args) => fitstation::app::run_live_cli(args)?,
    }
    Ok(())
}
