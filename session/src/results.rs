//! One line of `results.jsonl`: the raw comparison of a case ([`CaseReport`], flattened), its status
//! against the baseline, the outcome of every attempt when it was run again, and the triage entries
//! that applied — and reading such lines back, a line at a time.

use crate::baseline::Status;
use crate::compare::{CaseReport, Outcome};
use crate::error::SessionError;
use crate::triage::Triage;
use std::collections::BTreeSet;
use std::io::BufRead;
use std::path::Path;

/// A triage entry that turned a disagreement into `triaged`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct AppliedTriage {
    /// The VUID (or `output:…` key) the case disagreed on.
    pub key: String,
    /// Where the disagreement is: `model only`, `layer only` or `output`.
    pub side: String,
    pub kind: String,
    pub reason: String,
    /// The entry's reproducing case, when it names one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub case: Option<String>,
}

/// One line of `results.jsonl`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ResultLine {
    #[serde(flatten)]
    pub report: CaseReport,
    /// The status against the baseline (absent in files of older runs: derived from the outcome).
    #[serde(default = "unknown_status")]
    pub status: Status,
    /// The outcome of each attempt, the first included, when the case was run more than once.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub attempts: Vec<Outcome>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub triage: Vec<AppliedTriage>,
}

fn unknown_status() -> Status {
    Status::Missing
}

impl ResultLine {
    /// The status an older line without one gets: its outcome, with no baseline.
    fn settle(mut self) -> ResultLine {
        if self.status == Status::Missing {
            self.status = crate::baseline::Expectations::default()
                .status(&self.report, &[self.report.outcome]);
        }
        self
    }
}

/// The lines of `results.jsonl`, read one at a time (lines that do not parse are left out).
pub fn read_lines(path: &Path) -> Result<impl Iterator<Item = ResultLine>, SessionError> {
    let f =
        std::fs::File::open(path).map_err(|e| SessionError::io(path.display().to_string(), e))?;
    Ok(std::io::BufReader::new(f)
        .lines()
        .map_while(Result::ok)
        .filter_map(|l| serde_json::from_str::<ResultLine>(&l).ok())
        .map(ResultLine::settle))
}

/// The triage entries that explain a case's disagreements: one per VUID on which model and layer
/// differ that an entry covers, and the output entry named in the detail of a build's rays.
pub fn applied_triage(report: &CaseReport, triage: &Triage) -> Vec<AppliedTriage> {
    let m: BTreeSet<&String> = report.model.iter().collect();
    let l: BTreeSet<&String> = report.layer.iter().collect();
    let mut applied: Vec<AppliedTriage> = m
        .symmetric_difference(&l)
        .filter_map(|v| {
            let e = triage.covers(v)?;
            Some(AppliedTriage {
                key: (*v).clone(),
                side: if m.contains(v) {
                    "model only"
                } else {
                    "layer only"
                }
                .into(),
                kind: e.kind.clone(),
                reason: e.reason.clone(),
                case: e.case.clone(),
            })
        })
        .collect();
    for word in report.detail.split_whitespace() {
        if !word.starts_with("output:") {
            continue;
        }
        let key = word.trim_end_matches([':', ';', ',']);
        if applied.iter().any(|a| a.key == key) {
            continue;
        }
        if let Some(e) = triage.covers(key) {
            applied.push(AppliedTriage {
                key: key.into(),
                side: "output".into(),
                kind: e.kind.clone(),
                reason: e.reason.clone(),
                case: e.case.clone(),
            });
        }
    }
    applied
}
