//! `chronomap`: the command-line tool. Glue only: flags in `cli`, commands in `commands`,
//! algorithms in the library crates, files in `chronomap-io`, pictures in `chronomap-plot`,
//! what is shown and how the process ends in `output`.

mod bundled;
mod cli;
mod commands;
mod format;
mod output;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    output::set_quiet(cli.quiet);
    match commands::run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            let code = output::exit_code(&error);
            if code != 0 {
                errln!("error: {error:#}");
            }
            ExitCode::from(code)
        }
    }
}
