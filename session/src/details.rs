//! What a run keeps of each case that did not pass, for the report and for a person: the case file in
//! the folder of its outcome (`failures/`, `triaged/`, `unsupported/`, and `unexpected-passes/` for
//! cases the baseline expects to fail), and a line of `details.jsonl` with the model's violations
//! (with their paths) and the layer's messages in full. One appended file rather than a file per
//! case: creating a file is most of what keeping a case costs (a run of a few hundred triaged
//! cases spent a quarter of its wall time making inodes).

use crate::baseline::Status;
use crate::compare::{CaseReport, Outcome};
use harness::LayerMessage;
use model::{Case, Violation};
use std::path::{Path, PathBuf};

/// A case's line of `details.jsonl` (without its name).
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

/// The details file of a run.
pub const DETAILS_FILE: &str = "details.jsonl";

/// A line of [`DETAILS_FILE`]: the case's name and its details.
#[derive(serde::Serialize, serde::Deserialize)]
struct DetailsLine {
    case: String,
    #[serde(flatten)]
    details: CaseDetails,
}

/// The details line of a case, newline included.
pub fn details_line(case: &str, details: &CaseDetails) -> String {
    let line = DetailsLine {
        case: case.to_string(),
        details: details.clone(),
    };
    serde_json::to_string(&line).unwrap_or_default() + "\n"
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

/// Writes the case file of a case that did not pass, whole or not at all; whether the run keeps the
/// case (then its [`details_line`] goes to [`DETAILS_FILE`]). The file that could not be written,
/// with its error.
pub fn keep(
    out: &Path,
    folders: &mut MadeFolders,
    case: &Case,
    report: &CaseReport,
    status: Status,
) -> Result<bool, (PathBuf, std::io::Error)> {
    let Some(path) = case_path(out, report, status) else {
        return Ok(false);
    };
    if let Some(dir) = path.parent() {
        folders.make(dir).map_err(|e| (dir.to_path_buf(), e))?;
    }
    crate::outdir::write_atomically(&path, case.to_yaml().as_bytes())
        .map_err(|e| (path.clone(), e))?;
    Ok(true)
}

/// The details of every case of a run by name (the last line of a case where a resumed run wrote
/// it again); a line that does not parse (a torn last line) is left out.
pub fn read_details(out: &Path) -> std::collections::HashMap<String, CaseDetails> {
    let text = std::fs::read_to_string(out.join(DETAILS_FILE)).unwrap_or_default();
    text.lines()
        .filter_map(|l| serde_json::from_str::<DetailsLine>(l).ok())
        .map(|l| (l.case, l.details))
        .collect()
}
