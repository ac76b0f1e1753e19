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
        Command::Bench {
            what: BenchCommand::Deform(args),
        } => fitstation::deform::bench::run(args)?,
    }
    Ok(())
}
