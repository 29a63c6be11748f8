//! Whole-file reads with a size limit, so that a wrong path (`/dev/zero`, a disk image, a FIFO
//! that never ends) is an error naming the file instead of unbounded memory and time.

use std::io::{self, Read};
use std::path::Path;

/// The most bytes a whole-file reader of this crate takes (1 GiB): far above any model, map,
/// tree or log chronomap writes, and still a bounded allocation.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Reads `reader` to its end, or fails with [`io::ErrorKind::InvalidData`] once it yields more
/// than [`MAX_FILE_BYTES`].
pub(crate) fn read_to_end_bounded(reader: impl Read) -> io::Result<Vec<u8>> {
    read_at_most(reader, MAX_FILE_BYTES)
}

/// Reads `reader` to its end if it yields at most `max` bytes.
fn read_at_most(reader: impl Read, max: u64) -> io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    reader.take(max + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("larger than {max} bytes (is this the right file?)"),
        ));
    }
    Ok(bytes)
}

/// Opens `path` for reading if it is a regular file (or a link to one). A directory, a device
/// such as `/dev/zero` or a pipe is refused with [`io::ErrorKind::InvalidInput`] before anything
/// is read: checked before opening (opening a pipe waits for a writer) and again on the open
/// file (the path may have changed in between).
pub(crate) fn open_regular(path: &Path) -> io::Result<std::fs::File> {
    let not_regular = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            "it is not a regular file (a directory, a device or a pipe)",
        )
    };
    if !std::fs::metadata(path)?.is_file() {
        return Err(not_regular());
    }
    let file = std::fs::File::open(path)?;
    if !file.metadata()?.is_file() {
        return Err(not_regular());
    }
    Ok(file)
}

/// Opens `path` for streaming: a regular file or a pipe (`<(xz -dc …)`, `/dev/stdin`), not a
/// directory or a device such as `/dev/zero`, which is refused with
/// [`io::ErrorKind::InvalidInput`] before anything is read.
pub(crate) fn open_stream(path: &Path) -> io::Result<std::fs::File> {
    let streamable = |meta: &std::fs::Metadata| {
        #[cfg(unix)]
        let pipe = std::os::unix::fs::FileTypeExt::is_fifo(&meta.file_type());
        #[cfg(not(unix))]
        let pipe = false;
        meta.is_file() || pipe
    };
    let refused = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            "it is not a regular file or a pipe (a directory or a device)",
        )
    };
    if !streamable(&std::fs::metadata(path)?) {
        return Err(refused());
    }
    let file = std::fs::File::open(path)?;
    if !streamable(&file.metadata()?) {
        return Err(refused());
    }
    Ok(file)
}

/// The bytes of the regular file `path` (a directory, a device or a pipe is
/// refused before anything is read) if it holds at most `max` bytes, else an
/// [`io::ErrorKind::InvalidData`] error; for small files a face reads whole (a token, a key).
pub fn read_regular_at_most(path: &Path, max: u64) -> io::Result<Vec<u8>> {
    read_at_most(open_regular(path)?, max)
}

/// [`std::fs::read`] of a regular file ([`open_regular`]) with the [`MAX_FILE_BYTES`] limit.
pub(crate) fn read(path: &Path) -> io::Result<Vec<u8>> {
    read_to_end_bounded(open_regular(path)?)
}

/// [`std::fs::read_to_string`] with the [`MAX_FILE_BYTES`] limit.
#[cfg_attr(not(feature = "bt"), allow(dead_code))]
pub(crate) fn read_to_string(path: &Path) -> io::Result<String> {
    String::from_utf8(read(path)?).map_err(|_| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            "stream did not contain valid UTF-8",
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_reader_stops_at_the_limit() {
        let err = read_to_end_bounded(io::repeat(0)).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidData);
        assert_eq!(
            err.to_string(),
            "larger than 1073741824 bytes (is this the right file?)"
        );
        assert_eq!(read_to_end_bounded(&b"abc"[..]).unwrap(), b"abc");
    }

    #[cfg(unix)]
    #[test]
    fn devices_and_directories_are_refused_before_reading() {
        for path in ["/dev/zero", "/dev/null", "/"] {
            let err = read(Path::new(path)).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{path}");
            assert_eq!(
                err.to_string(),
                "it is not a regular file (a directory, a device or a pipe)"
            );
        }
        let file = std::env::temp_dir().join(format!("bounded-{}.txt", std::process::id()));
        std::fs::write(&file, "abc").unwrap();
        assert_eq!(read(&file).unwrap(), b"abc");
        std::fs::remove_file(&file).unwrap();
    }
}
