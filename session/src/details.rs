//! What a run keeps of each case that did not pass, for the report and for a person: a line of
//! `details.jsonl` with the model's violations (with their paths) and the layer's messages in full,
//! and the case file in the folder of its outcome — `failures/`, `case-errors/`, `unexpected-passes/`
//! for cases the baseline expects to fail, and `warnings/` for a rendered case that passed with
//! quality warnings (a hole where the spec's watertightness says "should"), so each can be replayed
//! and reported. The cases whose outcome is already explained — `triaged/` (a triage entry, which
//! names its own reproducing case), `unsupported/` (the profile), `not-realised/` (the harness) —
//! keep their case file only when the run is asked to (`--keep-all`): in `run_end_to_end`'s invalid
//! selection, 384 of the 520 cases are explained, and writing their files took a sixth of the
//! runner's CPU time and 6% of the run's wall time (creating a file is most of what keeping a case
//! costs, so the details of every kept case go to one appended file).

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

/// The folders of the outcomes that are already explained (a triage entry, the profile, the
/// harness): a run keeps their case files only when asked to ([`keeps_file`]).
pub const EXPLAINED_FOLDERS: [&str; 3] = ["triaged", "unsupported", "not-realised"];

/// Whether a run writes the case file of a case kept in `folder`: always, but for the
/// [`EXPLAINED_FOLDERS`] only when `keep_all`.
pub fn keeps_file(folder: &str, keep_all: bool) -> bool {
    keep_all || !EXPLAINED_FOLDERS.contains(&folder)
}

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

/// Writes the case file of a case that did not pass or passed with warnings ([`kept_folder`]; of an
/// explained outcome only when `keep_all`, [`keeps_file`]), whole or not at all; whether the run
/// keeps the case (then its [`details_line`] goes to [`DETAILS_FILE`], case file or not). The file
/// that could not be written, with its error.
pub fn keep(
    out: &Path,
    folders: &mut MadeFolders,
    case: &Case,
    report: &CaseReport,
    status: Status,
    keep_all: bool,
) -> Result<bool, (PathBuf, std::io::Error)> {
    let Some(folder) = kept_folder(report, status) else {
        return Ok(false);
    };
    if !keeps_file(folder, keep_all) {
        return Ok(true);
    }
    let path = out.join(folder).join(format!("{}.yaml", report.case));
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
    let text = crate::outdir::read_run_text(&out.join(DETAILS_FILE)).unwrap_or_default();
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

    /// An explained outcome keeps its details and, only with `keep_all`, its case file; a failure
    /// always keeps both; a pass neither.
    #[test]
    fn explained_outcomes_keep_their_case_file_only_when_asked() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../cases/hand/trace-indirect-records-32.yaml");
        let case = Case::read(
            &path.display().to_string(),
            &std::fs::read_to_string(&path).unwrap(),
        )
        .unwrap();
        let outcomes = [
            (Outcome::Triaged, Status::Triaged, Some("triaged"), false),
            (
                Outcome::Unsupported,
                Status::Skip,
                Some("unsupported"),
                false,
            ),
            (
                Outcome::NotRealised,
                Status::Skip,
                Some("not-realised"),
                false,
            ),
            (Outcome::Fail, Status::Fail, Some("failures"), true),
            (
                Outcome::CaseError,
                Status::CaseError,
                Some("case-errors"),
                true,
            ),
            (Outcome::Pass, Status::Pass, None, false),
        ];
        for (outcome, status, folder, always) in outcomes {
            for keep_all in [false, true] {
                let out = tempfile::tempdir().unwrap();
                let r = report(outcome, None);
                let kept = keep(
                    out.path(),
                    &mut MadeFolders::default(),
                    &case,
                    &r,
                    status,
                    keep_all,
                )
                .unwrap();
                assert_eq!(kept, folder.is_some(), "{outcome:?} keep_all {keep_all}");
                let file = folder.map(|f| out.path().join(f).join("c.yaml"));
                let written = file.as_ref().is_some_and(|f| f.is_file());
                assert_eq!(
                    written,
                    folder.is_some() && (always || keep_all),
                    "{outcome:?} keep_all {keep_all}"
                );
                if written {
                    let text = std::fs::read_to_string(file.unwrap()).unwrap();
                    assert_eq!(text, case.to_yaml());
                }
            }
        }
    }
}
