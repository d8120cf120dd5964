//! What a run keeps of each case that did not pass, for the report and for a person: the case file in
//! the folder of its outcome (`failures/`, `triaged/`, `unsupported/`, and `unexpected-passes/` for
//! cases the baseline expects to fail; `warnings/` for a rendered case that passed with quality
//! warnings — a hole where the spec's watertightness says "should" — so it can be replayed and
//! reported like a failure), and a line of `details.jsonl` with the model's violations
//! (with their paths) and the layer's messages in full. One appended file rather than a file per
//! case: creating a file is most of what keeping a case costs (a run of a few hundred triaged
//! cases spent a quarter of its wall time making inodes).

use crate::baseline::Status;
use crate::compare::{CaseReport, Outcome};
use harness::LayerMessage;
use model::{Case, Violation};
use std::borrow::Cow;
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

/// The folder of the cases that passed with quality warnings (see [`kept_folder`]).
pub const WARNINGS_FOLDER: &str = "warnings";

/// Whether a case passed with quality warnings: a rendered case whose records broke only what the
/// spec says implementations should do.
pub fn passed_with_warnings(report: &CaseReport) -> bool {
    report.outcome == Outcome::Pass && report.rendered.as_ref().is_some_and(|r| r.warnings > 0)
}

/// The folder a run keeps a case's file in: [`folder_of`] its outcome and status, else
/// [`WARNINGS_FOLDER`] for a case that passed with warnings; None for a case kept nowhere.
pub fn kept_folder(report: &CaseReport, status: Status) -> Option<&'static str> {
    folder_of(report.outcome, status)
        .or_else(|| passed_with_warnings(report).then_some(WARNINGS_FOLDER))
}

/// Every folder [`kept_folder`] names.
pub const CASE_FOLDERS: [&str; 7] = [
    "failures",
    "triaged",
    "unsupported",
    "not-realised",
    "unexpected-passes",
    "case-errors",
    WARNINGS_FOLDER,
];

/// Where a run keeps a case's file, when it keeps one.
pub fn case_path(out: &Path, report: &CaseReport, status: Status) -> Option<PathBuf> {
    kept_folder(report, status).map(|f| out.join(f).join(format!("{}.yaml", report.case)))
}

/// The details file of a run.
pub const DETAILS_FILE: &str = "details.jsonl";

/// A line of [`DETAILS_FILE`]: the case's name and its details (borrowed when written, owned when
/// read back).
#[derive(serde::Serialize, serde::Deserialize)]
struct DetailsLine<'a> {
    case: Cow<'a, str>,
    #[serde(flatten)]
    details: Cow<'a, CaseDetails>,
}

/// The details line of a case, newline included.
pub fn details_line(case: &str, details: &CaseDetails) -> String {
    let line = DetailsLine {
        case: Cow::Borrowed(case),
        details: Cow::Borrowed(details),
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

/// Writes the case file of a case that did not pass or passed with warnings ([`kept_folder`]), whole
/// or not at all; whether the run keeps the case (then its [`details_line`] goes to [`DETAILS_FILE`]). The file that could not be written,
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
        .map(|l| (l.case.into_owned(), l.details.into_owned()))
        .collect()
}

/// A report of case `c` with `outcome`, and rendered records of four rays with `warnings` where
/// given (for tests of where cases and their pictures are kept).
#[cfg(test)]
pub(crate) fn test_report(outcome: Outcome, warnings: Option<u64>) -> CaseReport {
    CaseReport {
        case: "c".into(),
        command: model::CommandId::TraceRays,
        target: None,
        outcome,
        model: vec![],
        layer: vec![],
        layer_other: vec![],
        output_matches: Some(true),
        rendered: warnings.map(|warnings| model::rendered::RenderedResult {
            rays: 4,
            warnings,
            ..Default::default()
        }),
        detail: String::new(),
        triage: vec![],
        millis: 1.0,
        phases: Default::default(),
        injection: None,
    }
}

#[cfg(test)]
mod tests {
    use super::test_report as report;
    use super::*;

    #[test]
    fn a_case_that_passed_with_warnings_is_kept_in_warnings() {
        let warned = report(Outcome::Pass, Some(3));
        assert!(passed_with_warnings(&warned));
        assert_eq!(kept_folder(&warned, Status::Pass), Some(WARNINGS_FOLDER));
        assert_eq!(
            case_path(Path::new("out"), &warned, Status::Pass),
            Some(PathBuf::from("out/warnings/c.yaml"))
        );
        // A clean pass is kept nowhere; the other folders take precedence over the warnings.
        assert_eq!(
            kept_folder(&report(Outcome::Pass, Some(0)), Status::Pass),
            None
        );
        assert_eq!(
            kept_folder(&report(Outcome::Pass, None), Status::Pass),
            None
        );
        assert_eq!(
            kept_folder(&warned, Status::UnexpectedPass),
            Some("unexpected-passes")
        );
        assert_eq!(
            kept_folder(&report(Outcome::Fail, Some(3)), Status::Fail),
            Some("failures")
        );
        assert!(CASE_FOLDERS.contains(&WARNINGS_FOLDER));
    }
}
