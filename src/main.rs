//! `chronomap`: the command-line tool. Glue only: flags in `cli`, commands in `commands`,
//! algorithms in `chronomap-core`, files and plots in `chronomap-io`.

mod bundled;
mod cli;
mod commands;
mod format;

use std::io::ErrorKind;
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match commands::run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // A closed pipe (`chronomap predict ... | head`) is not a failure.
            if error
                .chain()
                .filter_map(|e| e.downcast_ref::<std::io::Error>())
                .any(|e| e.kind() == ErrorKind::BrokenPipe)
            {
                return ExitCode::SUCCESS;
            }
            eprintln!("error: {error:#}");
            ExitCode::from(2)
        }
    }
}
