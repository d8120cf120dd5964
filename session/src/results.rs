//! One line of `results.jsonl`: the raw comparison of a case ([`CaseReport`], flattened), its status
//! against the baseline, the outcome of every attempt when it was run again, and the triage entries
//! that applied — and reading such lines back, a line at a time.

use crate::baseline::Status;
use crate::compare::{CaseReport, Outcome};
use crate::error::SessionError;
use crate::triage::{Triage, TriageEntry};
use std::path::Path;

/// The most bytes read as one line of `results.jsonl` (a rendered case's line is some kilobytes).
pub const RESULT_LINE_LIMIT: u64 = 64 * vk_registry::input::MIB;

/// The lines of `results.jsonl` as text, each at most [`RESULT_LINE_LIMIT`] bytes. A line that is not
/// UTF-8 is an error ([`vk_registry::input::is_not_utf8`]) and the lines after it follow; one too long
/// or an error of the reading is the last item.
pub fn text_lines(
    path: &Path,
) -> Result<impl Iterator<Item = std::io::Result<String>>, SessionError> {
    let f =
        std::fs::File::open(path).map_err(|e| SessionError::io(path.display().to_string(), e))?;
    let mut reader = std::io::BufReader::new(f);
    let mut ended = false;
    Ok(std::iter::from_fn(move || {
        if ended {
            return None;
        }
        let mut line = String::new();
        match vk_registry::input::read_line_at_most(
            &mut reader,
            &mut line,
            RESULT_LINE_LIMIT,
            "a line of results.jsonl",
        ) {
            Ok(true) => Some(Ok(line)),
            Ok(false) => {
                ended = true;
                None
            }
            Err(e) => {
                ended = !vk_registry::input::is_not_utf8(&e);
                Some(Err(e))
            }
        }
    }))
}

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

/// What is wrong with line `number` (1-based) of `path`, where it is not a result line:
/// `path:line:column: not a result line (the parser's words)`; None for a result line or a blank one.
pub fn unreadable_line(path: &Path, number: usize, text: &str) -> Option<String> {
    if text.trim().is_empty() {
        return None;
    }
    let e = serde_json::from_str::<ResultLine>(text).err()?;
    // The parser's words without its own place (line 1 of the one line it read).
    let words = e.to_string();
    let words = words
        .strip_suffix(&format!(" at line {} column {}", e.line(), e.column()))
        .unwrap_or(&words);
    Some(format!(
        "{}:{number}:{}: not a result line ({words})",
        path.display(),
        e.column().max(1)
    ))
}

/// The lines of `results.jsonl` that [`read_lines`] leaves out: the first `shown` with where and why
/// ([`unreadable_line`]), and how many there are in all. A line that is not UTF-8 is one of them; one
/// too long to read, or an I/O error, ends the reading, as it ends [`read_lines`]'.
pub fn unreadable_lines(path: &Path, shown: usize) -> Result<(Vec<String>, usize), SessionError> {
    let (mut first, mut count) = (Vec::new(), 0);
    for (n, line) in text_lines(path)?.enumerate() {
        let (problem, last) = match line {
            Ok(text) => match unreadable_line(path, n + 1, &text) {
                Some(p) => (p, false),
                None => continue,
            },
            Err(e) if vk_registry::input::is_not_utf8(&e) => (
                format!("{}:{}: not a result line ({e})", path.display(), n + 1),
                false,
            ),
            Err(e) => (
                format!(
                    "{}:{}: unreadable, and nothing after it is read ({e})",
                    path.display(),
                    n + 1
                ),
                true,
            ),
        };
        count += 1;
        if first.len() < shown {
            first.push(problem);
        }
        if last {
            break;
        }
    }
    Ok((first, count))
}

/// The lines of `results.jsonl`, read one at a time (lines that do not parse are left out;
/// [`unreadable_lines`] says which).
pub fn read_lines(path: &Path) -> Result<impl Iterator<Item = ResultLine>, SessionError> {
    Ok(text_lines(path)?
        .filter_map(Result::ok)
        .filter_map(|l| serde_json::from_str::<ResultLine>(&l).ok())
        .map(ResultLine::settle))
}

/// A run's triage entries by their id ([`TriageEntry::id`]), made once: a case's matches name their
/// entries by id.
pub struct TriageIds<'a> {
    by_id: std::collections::HashMap<String, &'a TriageEntry>,
}

impl<'a> TriageIds<'a> {
    pub fn new(triage: &'a Triage) -> TriageIds<'a> {
        let mut by_id = std::collections::HashMap::new();
        for e in &triage.entries {
            // The first entry of an id, as a search in file order finds it.
            by_id.entry(e.id()).or_insert(e);
        }
        TriageIds { by_id }
    }
}

/// The triage entries that explained a case's disagreements, as the comparison matched them
/// ([`CaseReport::triage`]): one per disagreement, with the entry's kind, reason and reproducing case.
pub fn applied_triage(report: &CaseReport, ids: &TriageIds) -> Vec<AppliedTriage> {
    report
        .triage
        .iter()
        .map(|m| {
            let entry = ids.by_id.get(m.entry.as_str()).copied();
            AppliedTriage {
                key: match &m.layer_vuid {
                    Some(w) => format!("{} -> {w}", m.vuid),
                    None => m.vuid.clone(),
                },
                side: match m.observed.as_str() {
                    "layer-silent" => "model only",
                    "layer-extra" => "layer only",
                    "layer-renames" => "renamed",
                    _ => "output",
                }
                .into(),
                kind: m.kind.name().into(),
                reason: entry.map(|e| e.reason.clone()).unwrap_or_default(),
                case: entry.and_then(|e| {
                    e.evidence
                        .iter()
                        .find(|ev| ev.starts_with("cases/"))
                        .cloned()
                }),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_that_is_not_utf8_is_named_and_the_lines_after_it_are_read() {
        let committed = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../results/nvidia-h200/run-2026-12-01-5a31f7d/findings/results.jsonl");
        let text = std::fs::read_to_string(committed).unwrap();
        let lines: Vec<&str> = text.lines().take(3).collect();
        assert_eq!(lines.len(), 3);
        let mut bytes = format!("{}\n", lines.join("\n")).into_bytes();
        // A flipped byte inside the second line's JSON.
        bytes[lines[0].len() + 1 + 5] = 0xfe;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("results.jsonl");
        std::fs::write(&path, bytes).unwrap();
        let read: Vec<String> = read_lines(&path).unwrap().map(|l| l.report.case).collect();
        let name = |l: &str| serde_json::from_str::<ResultLine>(l).unwrap().report.case;
        assert_eq!(read, [name(lines[0]), name(lines[2])]);
        let (named, count) = unreadable_lines(&path, 20).unwrap();
        assert_eq!(count, 1);
        assert_eq!(
            named,
            [format!(
                "{}:2: not a result line (not UTF-8 at column 6)",
                path.display()
            )]
        );
    }
}
