//! What the binary shows: results on stdout (text or `--json`), progress bars and errors on
//! stderr, exit codes.
//!
//! * Results go through [`outln!`](crate::outln!), which returns the write error instead of
//!   panicking, so a closed pipe (`chronomap inspect door.cmm | head -1`) ends the command
//!   quietly: `main` exits 0 when the first error in the chain is a broken pipe.
//! * Exit codes: 0 success (and a closed output pipe), 1 a failure at run time (a bad file, a
//!   model that cannot be built), 2 a usage error: what clap rejects, and a [`UsageError`]
//!   returned by a command for flags that contradict each other.
//! * [`ProgressBar`] draws a bar on stderr for work that takes more than a few seconds; it is
//!   hidden when stderr is not a terminal and with `--quiet`.

use std::fmt;
use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use chronomap_core::progress::Progress;
use serde::Serialize;

/// Writes a line of results to stdout and evaluates to `std::io::Result<()>`: use it with `?`
/// so that a closed pipe ends the command instead of panicking as `println!` would.
#[macro_export]
macro_rules! outln {
    () => {
        ::std::io::Write::write_all(&mut ::std::io::stdout().lock(), b"\n")
    };
    ($($arg:tt)*) => {
        ::std::io::Write::write_fmt(
            &mut ::std::io::stdout().lock(),
            format_args!("{}\n", format_args!($($arg)*)),
        )
    };
}

/// Writes to stdout without a newline; like [`outln!`](crate::outln!).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        ::std::io::Write::write_fmt(&mut ::std::io::stdout().lock(), format_args!($($arg)*))
    };
}

/// Writes a line to stderr (messages, warnings, the final error), ignoring a failed write:
/// a closed stderr (`chronomap … 2>&1 | true`) has nowhere to report to, and `eprintln!` would
/// panic there instead.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => {{
        let _ = ::std::io::Write::write_fmt(
            &mut ::std::io::stderr().lock(),
            format_args!("{}\n", format_args!($($arg)*)),
        );
    }};
}

/// Prints `value` as pretty JSON on stdout (the `--json` output of every command).
///
/// The text is made first and written in one go: a closed pipe is then the `io::Error` that
/// [`exit_code`] recognises (serde_json's writer would hide it in its own error), and a value
/// that cannot be serialised prints nothing.
pub fn print_json(value: &impl Serialize) -> anyhow::Result<()> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    let mut stdout = io::stdout().lock();
    stdout.write_all(text.as_bytes())?;
    stdout.flush()?;
    Ok(())
}

/// Prints a benchmark's result: with `json`, as one line of JSON (a log of runs keeps one run a
/// line), else as the text `text` writes.
pub fn print_bench<T: Serialize>(
    json: bool,
    bench: &T,
    text: impl FnOnce(&T) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    if json {
        crate::outln!("{}", serde_json::to_value(bench)?)?;
        Ok(())
    } else {
        text(bench)
    }
}

/// Flags that contradict each other or a value clap could not check: exit code 2, like
/// clap's own usage errors.
#[derive(Debug)]
pub struct UsageError(pub String);

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// A [`UsageError`] as an `anyhow::Error`.
pub fn usage(message: impl Into<String>) -> anyhow::Error {
    UsageError(message.into()).into()
}

static QUIET: AtomicBool = AtomicBool::new(false);

/// Hides every progress bar from now on (`--quiet`). Set once, by `main`, before any
/// command runs.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// A progress bar on stderr, fed by the [`Progress`] reports of the library. Hidden when
/// stderr is not a terminal (indicatif's rule) or with `--quiet`; cleared when dropped.
pub struct ProgressBar(indicatif::ProgressBar);

impl ProgressBar {
    /// A bar for work whose stages the library will announce.
    pub fn new() -> Self {
        let bar = if QUIET.load(Ordering::Relaxed) {
            indicatif::ProgressBar::hidden()
        } else {
            indicatif::ProgressBar::new(0)
        };
        bar.set_style(style(0));
        bar.enable_steady_tick(Duration::from_millis(200));
        ProgressBar(bar)
    }

    /// A bar for one stage of `total` steps that the binary itself drives.
    pub fn stage(name: &str, total: u64) -> Self {
        let bar = Self::new();
        Progress::stage(&bar, name, total);
        bar
    }
}

/// The bar of a stage of `total` steps; a stage of unknown length (`total` 0) shows a
/// spinner and the elapsed time instead of "0/0".
fn style(total: u64) -> indicatif::ProgressStyle {
    let template = if total == 0 {
        "{msg:>24} [{elapsed_precise}] {spinner}"
    } else {
        "{msg:>24} [{elapsed_precise}] {wide_bar} {pos}/{len} (eta {eta})"
    };
    indicatif::ProgressStyle::with_template(template).expect("a valid template")
}

impl Default for ProgressBar {
    fn default() -> Self {
        Self::new()
    }
}

impl Progress for ProgressBar {
    fn stage(&self, name: &str, total: u64) {
        self.0.set_style(style(total));
        self.0.set_message(name.to_string());
        self.0.set_length(total);
        self.0.set_position(0);
        self.0.reset_eta();
    }

    fn advance(&self, steps: u64) {
        self.0.inc(steps);
    }
}

impl Drop for ProgressBar {
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

/// `Ok(true)` if `result` failed only because stdout is a closed pipe: for commands whose
/// main work (writing a file) must still happen after their first report lines were lost.
pub fn closed_pipe(result: anyhow::Result<()>) -> anyhow::Result<bool> {
    match result {
        Ok(()) => Ok(false),
        Err(error) if exit_code(&error) == 0 => Ok(true),
        Err(error) => Err(error),
    }
}

/// The exit code for the error a command returned: 0 for a closed output pipe, 2 for a
/// [`UsageError`], 1 for everything else.
pub fn exit_code(error: &anyhow::Error) -> u8 {
    if error
        .chain()
        .filter_map(|e| e.downcast_ref::<io::Error>())
        .any(|e| e.kind() == io::ErrorKind::BrokenPipe)
    {
        0
    } else if error.downcast_ref::<UsageError>().is_some() {
        2
    } else {
        1
    }
}
