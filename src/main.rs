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
                errln!("{}", error_line(&error));
            }
            ExitCode::from(code)
        }
    }
}

/// `error: ` and the error with its causes, each shown once
/// ([`chronomap_core::error_chain::error_chain`]; not `{error:#}`, which repeats a cause an
/// error's message already holds).
fn error_line(error: &anyhow::Error) -> String {
    format!(
        "error: {}",
        chronomap_core::error_chain::error_chain(error.as_ref())
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The boosting error of the loop classifier ([`chronomap_lidar::AdaBoostError`]) under
    /// an error whose message holds it and whose source it is, as `#[error("training: {0}")]`
    /// over `#[from]` makes: `{:#}` printed the cause twice.
    #[derive(Debug)]
    struct Training(chronomap_lidar::AdaBoostError);

    impl std::fmt::Display for Training {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "training: {}", self.0)
        }
    }

    impl std::error::Error for Training {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.0)
        }
    }

    #[test]
    fn a_cause_is_printed_once() {
        let boost = chronomap_lidar::AdaBoostError::WorseThanChance(0.5);
        let error = anyhow::Error::from(Training(boost));
        assert_eq!(
            format!("{error:#}"),
            "training: the first stump has weighted error 0.5 >= 0.5: nothing to boost: the \
             first stump has weighted error 0.5 >= 0.5: nothing to boost"
        );
        assert_eq!(
            error_line(&error),
            "error: training: the first stump has weighted error 0.5 >= 0.5: nothing to boost"
        );
        let error = error.context("k.txt");
        assert_eq!(
            error_line(&error),
            "error: k.txt: training: the first stump has weighted error 0.5 >= 0.5: nothing to \
             boost"
        );
    }
}
