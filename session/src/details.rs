//! What a run keeps of each case that did not pass, for the report and for a person: the case file in
//! the folder of its outcome (`failures/`, `triaged/`, `unsupported/`, and `unexpected-passes/` for
//! cases the baseline expects to fail), and `details/NAME.json` with the model's violations (with
//! their paths) and the layer's messages in full.

use crate::baseline::Status;
use crate::compare::{CaseReport, Outcome};
use harness::LayerMessage;
use model::{Case, Violation};
use std::path::{Path, PathBuf};

/// `details/NAME.json`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CaseDetails {
    /// The model's violations of the case as it ran.
    #[serde(default)]
    pub violations: Vec<Violation>,
    /// Every message of the layer while the call was recorded.
    #[serde(default)]
    pub layer_messages: Vec<LayerMessage>,
}

/// The folder of a run that holds the case files of an outcome and status (None: passing cases keep
/// none). `failures/` holds failures only.
pub fn folder_of(outcome: Outcome, status: Status) -> Option<&'static str> {
    match outcome {
        Outcome::Pass if status == Status::UnexpectedPass => Some("unexpected-passes"),
        Outcome::Pass => None,
        Outcome::Triaged => Some("triaged"),
        Outcome::Unsupported => Some("unsupported"),
        Outcome::NotRealised => Some("not-realised"),
        Outcome::Fail | Outcome::Crash | Outcome::Timeout => Some("failures"),
        Outcome::CaseError => Some("case-errors"),
    }
}

/// Every folder [`folder_of`] names.
pub const CASE_FOLDERS: [&str; 6] = [
    "failures",
    "triaged",
    "unsupported",
    "not-realised",
    "unexpected-passes",
    "case-errors",
];

/// Where a run keeps a case's file, when it keeps one.
pub fn case_path(out: &Path, report: &CaseReport, status: Status) -> Option<PathBuf> {
    folder_of(report.outcome, status).map(|f| out.join(f).join(format!("{}.yaml", report.case)))
}

/// The details file of a case.
pub fn details_path(out: &Path, case: &str) -> PathBuf {
    out.join("details").join(format!("{case}.json"))
}

/// The folders of a run folder this process has made (or found): each is made once, not once per
/// case file written into it.
#[derive(Debug, Default)]
pub struct MadeFolders(std::collections::HashSet<PathBuf>);

impl MadeFolders {
    /// Makes `dir` and its parents unless this process made them already.
    pub fn make(&mut self, dir: &Path) -> std::io::Result<()> {
        if !self.0.contains(dir) {
            std::fs::create_dir_all(dir)?;
            self.0.insert(dir.to_path_buf());
        }
        Ok(())
    }
}

/// Writes what a run keeps of a case that did not pass (nothing for a pass): each file whole or not
/// at all. The first file that could not be written, with its error.
pub fn keep(
    out: &Path,
    folders: &mut MadeFolders,
    case: &Case,
    report: &CaseReport,
    status: Status,
    details: &CaseDetails,
) -> Result<(), (PathBuf, std::io::Error)> {
    let Some(path) = case_path(out, report, status) else {
        return Ok(());
    };
    let d = details_path(out, &case.name);
    let details = serde_json::to_string(details).unwrap_or_default();
    for (file, bytes) in [
        (&path, case.to_yaml().into_bytes()),
        (&d, details.into_bytes()),
    ] {
        if let Some(dir) = file.parent() {
            folders.make(dir).map_err(|e| (dir.to_path_buf(), e))?;
        }
        crate::outdir::write_atomically(file, &bytes).map_err(|e| (file.clone(), e))?;
    }
    Ok(())
}

/// Reads a case's details back (None when the run kept none).
pub fn read_details(out: &Path, case: &str) -> Option<CaseDetails> {
    let text = std::fs::read_to_string(details_path(out, case)).ok()?;
    serde_json::from_str(&text).ok()
}
