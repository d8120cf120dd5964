//! Reading the files a user names (registry files, cases, triage, profiles, pattern lists, run
//! folders) up to a size stated for their kind, so a wrong path (a device, a disk image, a log of
//! gigabytes) ends in an error naming the limit instead of memory sized by the input.
//!
//! Every reader of the workspace goes through these three; each kind's limit is a constant beside
//! its reader, far above what rtconf itself writes or the registry holds.

use std::io::{BufRead, Read};
use std::path::Path;

/// One mebibyte, for the limits.
pub const MIB: u64 = 1 << 20;

/// The error of a file or line past `limit` bytes (`what` names the kind, as the message says it):
/// of kind `Other`, where text that is not UTF-8 is `InvalidData` ([`is_not_utf8`]).
fn too_large(what: &str, limit: u64) -> std::io::Error {
    std::io::Error::other(format!(
        "larger than {}, the most rtconf reads as {what}",
        shown_size(limit)
    ))
}

/// A limit as said in a message: whole mebibytes where it is one, else bytes.
fn shown_size(limit: u64) -> String {
    if limit >= MIB && limit % MIB == 0 {
        format!("{} MiB", limit / MIB)
    } else {
        format!("{limit} bytes")
    }
}

/// The bytes of `path`, or an `Other` error where it holds more than `limit` (`what` names
/// the kind of file in the message, e.g. "a case file"). The buffer grows with what is read, never
/// past `limit + 1` bytes, whatever the file says its size is (a device or a pipe says none).
pub fn read_at_most(path: &Path, limit: u64, what: &str) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(what, limit));
    }
    Ok(bytes)
}

/// [`read_at_most`] as UTF-8 text (`InvalidData` where it is not, naming the line and column of the
/// first byte that is not).
pub fn read_text_at_most(path: &Path, limit: u64, what: &str) -> std::io::Result<String> {
    String::from_utf8(read_at_most(path, limit, what)?).map_err(|e| {
        let (line, column) = first_bad_byte(e.as_bytes(), e.utf8_error().valid_up_to());
        not_utf8(format!("line {line}, column {column}"))
    })
}

/// The line and column (from 1, the column in characters) of byte `bad` of `bytes`, valid UTF-8
/// before it ([`crate::error::line_col`] of that valid part).
fn first_bad_byte(bytes: &[u8], bad: usize) -> (usize, usize) {
    let before = std::str::from_utf8(&bytes[..bad]).unwrap_or_default();
    crate::error::line_col(before, before.len())
}

/// The error of text that is not UTF-8 (`not UTF-8 at PLACE`), told from others by [`is_not_utf8`].
#[derive(Debug)]
struct NotUtf8(String);

impl std::fmt::Display for NotUtf8 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "not UTF-8 at {}", self.0)
    }
}

impl std::error::Error for NotUtf8 {}

fn not_utf8(place: String) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidData, NotUtf8(place))
}

/// Whether `e` is this module's error of text that is not UTF-8 (after which [`read_line_at_most`]
/// stands at the next line), not an error of the reading itself.
pub fn is_not_utf8(e: &std::io::Error) -> bool {
    e.get_ref().is_some_and(|inner| inner.is::<NotUtf8>())
}

/// The next line of `reader` into `line` (cleared first, its `\n` or `\r\n` removed): `Ok(false)`
/// at the end; an `Other` error where a line runs past `limit` bytes before its newline
/// (`what` names the kind of line; the reader then stands inside it), an `InvalidData` one that
/// [`is_not_utf8`] where a line is not UTF-8 (the reader then stands at the next line).
pub fn read_line_at_most(
    reader: &mut impl BufRead,
    line: &mut String,
    limit: u64,
    what: &str,
) -> std::io::Result<bool> {
    line.clear();
    let mut bytes = Vec::new();
    let read = reader
        .take(limit.saturating_add(1))
        .read_until(b'\n', &mut bytes)?;
    if read == 0 {
        return Ok(false);
    }
    if bytes.last() == Some(&b'\n') {
        bytes.pop();
        if bytes.last() == Some(&b'\r') {
            bytes.pop();
        }
    } else if bytes.len() as u64 > limit {
        return Err(too_large(what, limit));
    }
    *line = String::from_utf8(bytes).map_err(|e| {
        let (_, column) = first_bad_byte(e.as_bytes(), e.utf8_error().valid_up_to());
        not_utf8(format!("column {column}"))
    })?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_file(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("vk-registry-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    #[test]
    fn a_file_at_the_limit_is_read_and_one_byte_more_is_refused() {
        let path = temp_file("ten", b"0123456789");
        assert_eq!(
            read_at_most(&path, 10, "a test file").unwrap(),
            b"0123456789"
        );
        let err = read_at_most(&path, 9, "a test file").unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::Other);
        assert_eq!(
            err.to_string(),
            "larger than 9 bytes, the most rtconf reads as a test file"
        );
    }

    #[test]
    fn an_endless_device_is_refused_at_the_limit() {
        let err = read_at_most(Path::new("/dev/zero"), 4 * MIB, "a case file").unwrap_err();
        assert_eq!(
            err.to_string(),
            "larger than 4 MiB, the most rtconf reads as a case file"
        );
        let mut zero = std::io::BufReader::new(std::fs::File::open("/dev/zero").unwrap());
        let mut line = String::new();
        let err = read_line_at_most(&mut zero, &mut line, MIB, "a result line").unwrap_err();
        assert_eq!(
            err.to_string(),
            "larger than 1 MiB, the most rtconf reads as a result line"
        );
    }

    #[test]
    fn lines_come_without_their_ends_and_the_last_may_lack_one() {
        let mut text = std::io::Cursor::new(b"a\r\nbcd\n\nlast".to_vec());
        let mut line = String::new();
        let mut lines = Vec::new();
        while read_line_at_most(&mut text, &mut line, 4, "a line").unwrap() {
            lines.push(line.clone());
        }
        assert_eq!(lines, ["a", "bcd", "", "last"]);
        let mut long = std::io::Cursor::new(b"abcd\n".to_vec());
        assert!(read_line_at_most(&mut long, &mut line, 3, "a line").is_err());
    }

    #[test]
    fn text_that_is_not_utf8_says_where() {
        let path = temp_file("latin1", b"line\nna\xc3\xafve \xe9t\xe9");
        let err = read_text_at_most(&path, 100, "a test file").unwrap_err();
        assert_eq!(err.to_string(), "not UTF-8 at line 2, column 7");
        let mut text = std::io::Cursor::new(b"na\xc3\xafve \xe9t\nnext".to_vec());
        let mut line = String::new();
        let err = read_line_at_most(&mut text, &mut line, 100, "a line").unwrap_err();
        assert!(is_not_utf8(&err));
        assert_eq!(err.to_string(), "not UTF-8 at column 7");
        assert!(read_line_at_most(&mut text, &mut line, 100, "a line").unwrap());
        assert_eq!(line, "next");
    }
}
