//! The error of the small line-oriented text files of the `bt` feature (bt scripts, fault
//! files, leaf parameters): the file, the 1-based line if the problem is on one, and what is
//! wrong, shown as `file:line: what`.

use std::fmt;
use std::io;
use std::path::Path;

/// What is wrong in a [`LineError`].
pub trait LineErrorKind: fmt::Display + fmt::Debug {
    /// The read failure of a kind whose message is `cannot read FILE: reason` instead of
    /// `FILE: kind`; by default none is.
    fn cannot_read(&self) -> Option<&io::Error> {
        None
    }
}

/// Why a text file could not be read: the file, the 1-based line and the problem `K`.
#[derive(Debug)]
pub struct LineError<K> {
    file: String,
    line: Option<usize>,
    kind: K,
}

impl<K: LineErrorKind> fmt::Display for LineError<K> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (file, kind) = (&self.file, &self.kind);
        match (kind.cannot_read(), self.line) {
            (Some(io), _) => write!(f, "cannot read {file}: {io}"),
            (None, Some(line)) => write!(f, "{file}:{line}: {kind}"),
            (None, None) => write!(f, "{file}: {kind}"),
        }
    }
}

impl<K: LineErrorKind> std::error::Error for LineError<K> {}

impl<K> LineError<K> {
    pub(crate) fn new(file: &str, line: Option<usize>, kind: K) -> Self {
        LineError {
            file: file.to_owned(),
            line,
            kind,
        }
    }

    /// The file.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The 1-based line, if the problem is on one.
    pub fn line(&self) -> Option<usize> {
        self.line
    }

    /// What is wrong.
    pub fn kind(&self) -> &K {
        &self.kind
    }
}

/// Reads the text file `path` and hands its name (for messages) and text to `parse`; a file
/// that cannot be read is the error `io` makes of the failure, without a line.
pub(crate) fn parse_text_file<T, K>(
    path: &Path,
    io: fn(io::Error) -> K,
    parse: impl FnOnce(&str, &str) -> Result<T, LineError<K>>,
) -> Result<T, LineError<K>> {
    let name = path.display().to_string();
    let text =
        crate::bounded::read_to_string(path).map_err(|e| LineError::new(&name, None, io(e)))?;
    parse(&name, &text)
}

/// The lines of `text` that hold something, numbered from 1: what is left of each after a
/// `#` comment is cut off and white space trimmed, blank results skipped.
pub(crate) fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().filter_map(|(i, raw)| {
        let content = raw.split('#').next().unwrap_or("").trim();
        (!content.is_empty()).then_some((i + 1, content))
    })
}

#[cfg(test)]
mod tests {
    use crate::monitor_faults::{FaultFileErrorKind, read_fault_file};
    use crate::sbt_params::{SbtParamsErrorKind, read_leaf_params};

    #[test]
    fn a_missing_file_names_itself() {
        let faults = read_fault_file("no-such-faults.txt").unwrap_err();
        assert!(matches!(faults.kind(), FaultFileErrorKind::Io(_)));
        let params = read_leaf_params("no-such-params.csv").unwrap_err();
        assert!(matches!(params.kind(), SbtParamsErrorKind::Io(_)));
        for (message, start) in [
            (faults.to_string(), "no-such-faults.txt: cannot read: "),
            (params.to_string(), "cannot read no-such-params.csv: "),
        ] {
            assert!(message.starts_with(start), "{message}");
        }
    }
}
