//! The error type shared by every reader: each variant says where the problem is.

use std::fmt;

/// Where in an input an error was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A line and column in a text (both 1-based; the column counts characters).
    LineCol { line: usize, column: usize },
    /// A JSON path such as `$.validation.vkCmdDraw.core[3].vuid`.
    JsonPath(String),
    /// A JSON path together with the line and column where the value starts.
    JsonPathAt {
        path: String,
        line: usize,
        column: usize,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::LineCol { line, column } => write!(f, "{line}:{column}"),
            Location::JsonPath(p) => write!(f, "{p}"),
            Location::JsonPathAt { path, line, column } => write!(f, "{line}:{column} ({path})"),
        }
    }
}

/// Every error of this crate.
#[derive(Debug, thiserror::Error)]
pub enum RegistryError {
    /// A file or directory that does not exist.
    #[error("{path}: file not found")]
    NotFound { path: String },
    /// Any other I/O failure.
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// Malformed or unexpected input, with its location.
    #[error("{origin}:{location}: {message}")]
    Parse {
        /// The file (or `<string>`) that was read.
        origin: String,
        location: Location,
        message: String,
    },
    /// A name that a lookup did not find.
    #[error("unknown name `{name}`")]
    UnknownName { name: String },
}

impl RegistryError {
    /// A parse error at a byte offset of `text`.
    pub fn at_offset(origin: &str, text: &str, offset: usize, message: impl Into<String>) -> Self {
        let (line, column) = line_col(text, offset);
        RegistryError::Parse {
            origin: origin.to_string(),
            location: Location::LineCol { line, column },
            message: message.into(),
        }
    }

    /// A parse error at a known line and column.
    pub fn at_line_col(
        origin: &str,
        line: usize,
        column: usize,
        message: impl Into<String>,
    ) -> Self {
        RegistryError::Parse {
            origin: origin.to_string(),
            location: Location::LineCol { line, column },
            message: message.into(),
        }
    }

    /// The location of a parse error, if it is one.
    pub fn location(&self) -> Option<&Location> {
        match self {
            RegistryError::Parse { location, .. } => Some(location),
            _ => None,
        }
    }

    /// Replace the origin of a parse error (used when a string parser is called for a file).
    pub fn with_origin(self, path: &str) -> Self {
        match self {
            RegistryError::Parse {
                location, message, ..
            } => RegistryError::Parse {
                origin: path.to_string(),
                location,
                message,
            },
            other => other,
        }
    }

    /// An I/O error for `path`, turning "not found" into [`RegistryError::NotFound`].
    pub fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        let path = path.display().to_string();
        if source.kind() == std::io::ErrorKind::NotFound {
            RegistryError::NotFound { path }
        } else {
            RegistryError::Io { path, source }
        }
    }
}

/// 1-based line and column (in characters) of a byte offset; offsets past the end are clamped.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |p| p + 1);
    let column = text[line_start..offset].chars().count() + 1;
    (line, column)
}

/// `s` as quoted in an error message: at most 80 characters, with `…` where it was cut, so that an
/// error about a huge value stays readable.
pub fn excerpt(s: &str) -> std::borrow::Cow<'_, str> {
    const MAX: usize = 80;
    match s.char_indices().nth(MAX) {
        None => s.into(),
        Some((cut, _)) => format!("{}…", &s[..cut]).into(),
    }
}

/// The most bytes read from one registry file (vk.xml is about 2 MB, validusage.json about 10 MB).
pub const REGISTRY_FILE_LIMIT: u64 = 256 * crate::input::MIB;

/// Read a whole registry file as UTF-8 (at most [`REGISTRY_FILE_LIMIT`] bytes), with errors
/// naming the path.
pub fn read_to_string(path: &std::path::Path) -> Result<String, RegistryError> {
    let bytes = crate::input::read_at_most(path, REGISTRY_FILE_LIMIT, "a registry file")
        .map_err(|e| RegistryError::io(path, e))?;
    String::from_utf8(bytes).map_err(|e| {
        let off = e.utf8_error().valid_up_to();
        let text = String::from_utf8_lossy(e.as_bytes()).into_owned();
        RegistryError::at_offset(&path.display().to_string(), &text, off, "invalid UTF-8")
    })
}
