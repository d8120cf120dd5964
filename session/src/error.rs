//! The session's error type: every failure says what was being done and, where it helps, how to fix it.

use harness::error::SETUP_COMMAND;

/// What stopped a session step.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// A case or triage file that does not parse (with its line and column).
    #[error(transparent)]
    Case(#[from] model::case::CaseError),
    #[error("{what}: {source}")]
    Io {
        what: String,
        source: std::io::Error,
    },
    /// The registry sources could not be read.
    #[error("{problem}{hint}")]
    Registry { problem: String, hint: String },
    #[error("profile `{name}`: {problem}")]
    Profile { name: String, problem: String },
    #[error("driver `{driver}`: no ICD manifest at {path} (for lavapipe run `{SETUP_COMMAND}`)")]
    NoDriver { driver: String, path: String },
    #[error(transparent)]
    Harness(#[from] harness::HarnessError),
    #[error(transparent)]
    Generate(#[from] generator::GenError),
    /// A request the session cannot make sense of (an unknown command name).
    #[error("{0}")]
    Usage(String),
}

impl SessionError {
    pub fn io(what: impl Into<String>, source: std::io::Error) -> SessionError {
        SessionError::Io {
            what: what.into(),
            source,
        }
    }
}
