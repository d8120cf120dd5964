//! What a driver team expects of a run, in the plain text files deqp-runner uses — a baseline of
//! expected failures, a skips list and a flakes list — and each case's status against them, kept apart
//! from its raw outcome.
//!
//! **Baseline** (`--baseline FILE`): one expected failure per line, `KEY,STATUS`, where `KEY` is a case
//! name or a VUID (`VUID-…`) and `STATUS` the raw outcome expected (`fail`, `crash` or `timeout`, any
//! case). `*` in a key stands for any run of characters. A VUID key matches a case that targets the
//! VUID or on which model and layer disagree about it. A case that several lines match expects any of
//! their statuses (a driver bug that loses the device on one run and hangs on another).
//!
//! **Skips** and **flakes** (`--skips FILE`, `--flakes FILE`): one regular expression per line, searched
//! (unanchored, as deqp-runner does) in the case's name and in the VUID it targets. Skipped cases are
//! not run; a failing case on the flakes list is a `flake`, not a failure.
//!
//! In every file `#` starts a comment and blank lines are ignored. A line that does not parse is an
//! error naming the file and line; nothing panics on input.

use crate::compare::{CaseReport, Outcome};
use crate::error::SessionError;
use std::collections::BTreeSet;
use std::path::Path;

/// A case's status against the baseline (deqp-runner's vocabulary). The raw outcome stays in
/// [`CaseReport::outcome`].
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Model and driver agree.
    Pass,
    /// They disagree exactly as a triage file says.
    Triaged,
    /// The device or harness cannot realise the case.
    Skip,
    /// An unexpected failure.
    Fail,
    /// An unexpected crash.
    Crash,
    /// An unexpected timeout.
    Timeout,
    /// Failed as the baseline says it does.
    ExpectedFail,
    /// The baseline expects a failure, and the case passed (update the baseline).
    UnexpectedPass,
    /// Changed outcome when run again, or failed and is on the flakes list.
    Flake,
    /// Planned for the run (in `caselist.txt`) but without a result.
    Missing,
    /// The case is at fault, not the driver (never expected by a baseline: fix the case).
    CaseError,
}

impl Status {
    pub const ALL: [Status; 11] = [
        Status::Pass,
        Status::Triaged,
        Status::Skip,
        Status::Fail,
        Status::Crash,
        Status::Timeout,
        Status::ExpectedFail,
        Status::UnexpectedPass,
        Status::Flake,
        Status::Missing,
        Status::CaseError,
    ];

    /// Whether this status makes a run fail (its exit status).
    pub fn is_failure(self) -> bool {
        matches!(
            self,
            Status::Fail
                | Status::Crash
                | Status::Timeout
                | Status::UnexpectedPass
                | Status::Missing
                | Status::CaseError
        )
    }

    /// The name used in files and on the console (`expected-fail`).
    pub fn name(self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Triaged => "triaged",
            Status::Skip => "skip",
            Status::Fail => "fail",
            Status::Crash => "crash",
            Status::Timeout => "timeout",
            Status::ExpectedFail => "expected-fail",
            Status::UnexpectedPass => "unexpected-pass",
            Status::Flake => "flake",
            Status::Missing => "missing",
            Status::CaseError => "case-error",
        }
    }

    /// What the status means, for the report's legend.
    pub fn meaning(self) -> &'static str {
        match self {
            Status::Pass => "model and driver agree",
            Status::Triaged => "they disagree exactly as a triage entry says",
            Status::Skip => "the device or the harness cannot realise the case",
            Status::Fail => "an unexpected disagreement",
            Status::Crash => "the driver, the layer or the worker died",
            Status::Timeout => "the case ran past its time limit",
            Status::ExpectedFail => "failed as the baseline says",
            Status::UnexpectedPass => "the baseline expects a failure and the case passed",
            Status::Flake => "changed outcome when run again, or on the flakes list",
            Status::Missing => "planned but without a result",
            Status::CaseError => "the case is at fault, not the driver",
        }
    }
}

impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One expected failure of a baseline file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BaselineEntry {
    /// A case name or VUID pattern (`*` for any run of characters).
    pub key: String,
    /// The raw outcome expected: fail, crash or timeout.
    pub outcome: Outcome,
    /// `file:line` of the entry.
    pub origin: String,
}

/// A regular expression of a skips or flakes file.
#[derive(Debug, Clone)]
pub struct CasePattern {
    pub regex: regex::Regex,
    pub origin: String,
}

/// The baseline, skips and flakes of a run (each may be empty).
#[derive(Debug, Clone, Default)]
pub struct Expectations {
    pub baseline: Vec<BaselineEntry>,
    pub skips: Vec<CasePattern>,
    pub flakes: Vec<CasePattern>,
    /// The files read, for the summary.
    pub files: Vec<String>,
}

/// A line of an expectations file that does not parse.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LineError {
    pub path: String,
    pub line: usize,
    pub problem: String,
}

impl std::fmt::Display for LineError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.path, self.line, self.problem)
    }
}

/// The meaningful lines of a file: (line number from 1, text without comment, trimmed).
fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().filter_map(|(i, l)| {
        let l = l.split_once('#').map_or(l, |(before, _)| before).trim();
        (!l.is_empty()).then_some((i + 1, l))
    })
}

/// Parses a baseline file's text: the entries, and an error per line that does not parse.
pub fn parse_baseline(path: &str, text: &str) -> (Vec<BaselineEntry>, Vec<LineError>) {
    let mut entries = Vec::new();
    let mut errors = Vec::new();
    for (line, l) in lines(text) {
        let err = |problem: String| LineError {
            path: path.into(),
            line,
            problem,
        };
        let Some((key, status)) = l.rsplit_once(',') else {
            errors.push(err(format!(
                "expected `CASE-OR-VUID,STATUS` (STATUS one of fail, crash, timeout), found `{l}`"
            )));
            continue;
        };
        let (key, status) = (key.trim(), status.trim());
        let outcome = match status.to_ascii_lowercase().as_str() {
            "fail" => Outcome::Fail,
            "crash" => Outcome::Crash,
            "timeout" => Outcome::Timeout,
            other => {
                errors.push(err(format!(
                    "status `{other}` is not an expected failure (one of fail, crash, timeout)"
                )));
                continue;
            }
        };
        if key.is_empty() || key.contains(char::is_whitespace) {
            errors.push(err(format!(
                "`{key}` is not a case name or VUID (no spaces, not empty)"
            )));
            continue;
        }
        entries.push(BaselineEntry {
            key: key.into(),
            outcome,
            origin: format!("{path}:{line}"),
        });
    }
    (entries, errors)
}

/// The compiled size one pattern of a skips or flakes file may take. Case names and VUIDs are short
/// ASCII words, and a pattern for them compiles to a few kilobytes; the regex crate's own default,
/// ten megabytes, let one line of a hostile file (`[a-z]{4294967295}`) take 40 ms to refuse and a
/// file of 1,250 such lines 40 s. At this size a refusal takes about a millisecond; Unicode classes
/// repeated many times (`\w{30}`) pass it only written in ASCII (`[0-9A-Za-z_]{30}`).
pub const PATTERN_SIZE_LIMIT: usize = 256 << 10;

/// The bad lines of a skips or flakes file that are reported before the rest is left unread: enough
/// to fix a file by, while a file of bad lines costs no more than this many refusals.
pub const PATTERN_ERRORS_SHOWN: usize = 20;

/// Parses a skips or flakes file's text: one regular expression per line. After
/// [`PATTERN_ERRORS_SHOWN`] bad lines the rest of the file is not read, and one more error says so.
pub fn parse_patterns(path: &str, text: &str) -> (Vec<CasePattern>, Vec<LineError>) {
    let mut patterns = Vec::new();
    let mut errors = Vec::new();
    for (line, l) in lines(text) {
        if errors.len() == PATTERN_ERRORS_SHOWN {
            errors.push(LineError {
                path: path.into(),
                line,
                problem: format!(
                    "not read: the file has {PATTERN_ERRORS_SHOWN} bad lines before this one"
                ),
            });
            break;
        }
        match regex::RegexBuilder::new(l)
            .size_limit(PATTERN_SIZE_LIMIT)
            .build()
        {
            Ok(regex) => patterns.push(CasePattern {
                regex,
                origin: format!("{path}:{line}"),
            }),
            Err(e) => errors.push(LineError {
                path: path.into(),
                line,
                problem: format!("not a regular expression: {e}"),
            }),
        }
    }
    (patterns, errors)
}

/// The most bytes read from one baseline, skips or flakes file.
pub const PATTERN_FILE_LIMIT: u64 = 64 * vk_registry::input::MIB;

fn read(path: &Path) -> Result<String, SessionError> {
    vk_registry::input::read_text_at_most(path, PATTERN_FILE_LIMIT, "a list of cases or patterns")
        .map_err(|e| SessionError::io(path.display().to_string(), e))
}

/// Every line error of a file as one usage error.
fn usage(errors: Vec<LineError>) -> SessionError {
    SessionError::Usage(
        errors
            .iter()
            .map(|e| e.to_string())
            .collect::<Vec<_>>()
            .join("\n"),
    )
}

impl Expectations {
    /// Reads the named files; any line that does not parse is an error naming its file and line.
    pub fn load(
        baseline: Option<&Path>,
        skips: Option<&Path>,
        flakes: Option<&Path>,
    ) -> Result<Expectations, SessionError> {
        let mut e = Expectations::default();
        if let Some(p) = baseline {
            let (entries, errors) = parse_baseline(&p.display().to_string(), &read(p)?);
            if !errors.is_empty() {
                return Err(usage(errors));
            }
            e.baseline = entries;
            e.files.push(format!("baseline {}", p.display()));
        }
        for (path, into, what) in [
            (skips, &mut e.skips, "skips"),
            (flakes, &mut e.flakes, "flakes"),
        ] {
            if let Some(p) = path {
                let (patterns, errors) = parse_patterns(&p.display().to_string(), &read(p)?);
                if !errors.is_empty() {
                    return Err(usage(errors));
                }
                *into = patterns;
                e.files.push(format!("{what} {}", p.display()));
            }
        }
        Ok(e)
    }

    /// Whether the skips list keeps a case (by name and target VUID) from running.
    pub fn skips(&self, name: &str, target: Option<&str>) -> bool {
        matches_any(&self.skips, name, target)
    }

    /// The baseline entries that expect a failure of this case (a case whose driver bug shows
    /// one way or another, a lost device or a hang, is listed once with each).
    pub fn expected<'a>(
        &'a self,
        report: &'a CaseReport,
    ) -> impl Iterator<Item = &'a BaselineEntry> + 'a {
        let disagreement: BTreeSet<&String> = {
            let m: BTreeSet<&String> = report.model.iter().collect();
            let l: BTreeSet<&String> = report.layer.iter().collect();
            m.symmetric_difference(&l).copied().collect()
        };
        self.baseline.iter().filter(move |e| {
            if e.key.starts_with("VUID-") {
                report
                    .target
                    .as_deref()
                    .is_some_and(|t| wildcard_match(&e.key, t))
                    || disagreement.iter().any(|v| wildcard_match(&e.key, v))
            } else {
                wildcard_match(&e.key, &report.case)
            }
        })
    }

    /// The status of a case against these expectations, from its report and the outcomes of every
    /// attempt (the first is the report's; retries follow).
    pub fn status(&self, report: &CaseReport, attempts: &[Outcome]) -> Status {
        if attempts.windows(2).any(|w| w[0] != w[1]) {
            return Status::Flake;
        }
        let mut expected = self.expected(report).map(|e| e.outcome).peekable();
        let any_expected = expected.peek().is_some();
        match report.outcome {
            o @ (Outcome::Fail | Outcome::Crash | Outcome::Timeout) => {
                if expected.any(|e| e == o) {
                    Status::ExpectedFail
                } else if matches_any(&self.flakes, &report.case, report.target.as_deref()) {
                    Status::Flake
                } else {
                    match o {
                        Outcome::Fail => Status::Fail,
                        Outcome::Crash => Status::Crash,
                        _ => Status::Timeout,
                    }
                }
            }
            Outcome::Pass | Outcome::Triaged if any_expected => Status::UnexpectedPass,
            Outcome::Pass => Status::Pass,
            Outcome::Triaged => Status::Triaged,
            Outcome::Unsupported | Outcome::NotRealised => Status::Skip,
            Outcome::CaseError => Status::CaseError,
        }
    }
}

fn matches_any(patterns: &[CasePattern], name: &str, target: Option<&str>) -> bool {
    patterns
        .iter()
        .any(|p| p.regex.is_match(name) || target.is_some_and(|t| p.regex.is_match(t)))
}

/// Whether `text` matches `pattern`, where `*` stands for any run of characters.
pub fn wildcard_match(pattern: &str, text: &str) -> bool {
    let mut parts = pattern.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = text.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    for (i, part) in parts.iter().enumerate() {
        if i == parts.len() - 1 {
            return rest.ends_with(part);
        }
        match rest.find(part) {
            Some(at) => rest = &rest[at + part.len()..],
            None => return false,
        }
    }
    rest.is_empty()
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::CommandId;

    fn report(case: &str, outcome: Outcome, target: Option<&str>, model: &[&str]) -> CaseReport {
        CaseReport {
            case: case.into(),
            command: CommandId::TraceRaysIndirect,
            target: target.map(String::from),
            outcome,
            model: model.iter().map(|s| s.to_string()).collect(),
            layer: vec![],
            layer_other: vec![],
            output_matches: None,
            rendered: None,
            detail: String::new(),
            triage: vec![],
            millis: 1.0,
            phases: Default::default(),
            injection: None,
        }
    }

    fn expectations(baseline: &str, flakes: &str) -> Expectations {
        let (b, e1) = parse_baseline("baseline.txt", baseline);
        let (f, e2) = parse_patterns("flakes.txt", flakes);
        assert!(e1.is_empty() && e2.is_empty(), "{e1:?} {e2:?}");
        Expectations {
            baseline: b,
            flakes: f,
            ..Default::default()
        }
    }

    #[test]
    fn baseline_lines_parse_with_comments_and_bad_lines_name_their_line() {
        let text = "# expected failures\n\ncase-a,Fail\nVUID-vkCmdTraceRaysKHR-*-03429 , crash # gap\nno-status\ncase-b,passed\n";
        let (entries, errors) = parse_baseline("b.txt", text);
        assert_eq!(
            entries,
            vec![
                BaselineEntry {
                    key: "case-a".into(),
                    outcome: Outcome::Fail,
                    origin: "b.txt:3".into()
                },
                BaselineEntry {
                    key: "VUID-vkCmdTraceRaysKHR-*-03429".into(),
                    outcome: Outcome::Crash,
                    origin: "b.txt:4".into()
                },
            ]
        );
        assert_eq!(
            errors.iter().map(|e| e.line).collect::<Vec<_>>(),
            vec![5, 6]
        );
        assert!(errors[0]
            .to_string()
            .starts_with("b.txt:5: expected `CASE-OR-VUID,STATUS`"));
        assert!(errors[1].problem.contains("`passed`"));
    }

    #[test]
    fn pattern_files_report_bad_regexes_by_line() {
        let (p, e) = parse_patterns("s.txt", "^trace-.*\n# c\n(unclosed\n");
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].origin, "s.txt:1");
        assert_eq!(e.len(), 1);
        assert_eq!(e[0].line, 3);
    }

    #[test]
    fn a_file_of_huge_patterns_is_refused_in_bounded_time() {
        // 1,250 lines each asking for a program past the size limit: the first twenty are named, then
        // the reading stops with a line that says so.
        let text = "x\n".to_string() + &"(?i)^BUILD-[a-z0-9]{4294967295}\n".repeat(1250);
        let started = std::time::Instant::now();
        let (p, e) = parse_patterns("s.txt", &text);
        assert!(
            started.elapsed().as_secs_f64() < 2.0,
            "{:?}",
            started.elapsed()
        );
        assert_eq!(p.len(), 1);
        assert_eq!(e.len(), PATTERN_ERRORS_SHOWN + 1);
        assert_eq!(
            e.iter().map(|e| e.line).collect::<Vec<_>>(),
            (2..=PATTERN_ERRORS_SHOWN + 2).collect::<Vec<_>>()
        );
        assert!(e[0].problem.contains("size limit"), "{}", e[0]);
        assert!(
            e[PATTERN_ERRORS_SHOWN].problem.contains("not read"),
            "{}",
            e[PATTERN_ERRORS_SHOWN]
        );
        // What the limit leaves: the patterns a driver team writes for case names and VUIDs.
        let (p, e) = parse_patterns(
            "s.txt",
            "(?i)^BUILD-[a-z]+-(valid|invalid)\nVUID-vkCmdTraceRaysNV-.*-0[0-9]{4}\n[0-9A-Za-z_]{30}\n",
        );
        assert!(e.is_empty(), "{e:?}");
        assert_eq!(p.len(), 3);
    }

    #[test]
    fn statuses_against_the_baseline_follow_deqp_runner() {
        let x = expectations(
            "known-fail,fail\nVUID-vkCmdTraceRaysIndirectKHR-stride-*,fail\nknown-crash,crash\n",
            "^flaky-",
        );
        let st = |r: &CaseReport| x.status(r, &[r.outcome]);
        assert_eq!(
            st(&report("known-fail", Outcome::Fail, None, &[])),
            Status::ExpectedFail
        );
        assert_eq!(
            st(&report("known-fail", Outcome::Pass, None, &[])),
            Status::UnexpectedPass
        );
        assert_eq!(
            st(&report("known-fail", Outcome::Triaged, None, &[])),
            Status::UnexpectedPass
        );
        // Expected to crash, but failed: still unexpected.
        assert_eq!(
            st(&report("known-crash", Outcome::Fail, None, &[])),
            Status::Fail
        );
        assert_eq!(
            st(&report("known-crash", Outcome::Crash, None, &[])),
            Status::ExpectedFail
        );
        // A VUID key matches the target and the disagreement.
        let by_target = report(
            "x-1",
            Outcome::Fail,
            Some("VUID-vkCmdTraceRaysIndirectKHR-stride-03686"),
            &[],
        );
        assert_eq!(st(&by_target), Status::ExpectedFail);
        let by_disagreement = report(
            "valid-2",
            Outcome::Fail,
            None,
            &["VUID-vkCmdTraceRaysIndirectKHR-stride-03690"],
        );
        assert_eq!(st(&by_disagreement), Status::ExpectedFail);
        assert_eq!(st(&report("other", Outcome::Fail, None, &[])), Status::Fail);
        assert_eq!(
            st(&report("other", Outcome::Timeout, None, &[])),
            Status::Timeout
        );
        assert_eq!(
            st(&report("other", Outcome::Unsupported, None, &[])),
            Status::Skip
        );
        assert_eq!(
            st(&report("other", Outcome::Triaged, None, &[])),
            Status::Triaged
        );
        assert_eq!(
            st(&report("flaky-1", Outcome::Crash, None, &[])),
            Status::Flake
        );
        // A case whose attempts differ is a flake whatever the baseline says.
        let r = report("known-fail", Outcome::Fail, None, &[]);
        assert_eq!(x.status(&r, &[Outcome::Fail, Outcome::Pass]), Status::Flake);
        assert_eq!(
            x.status(&r, &[Outcome::Fail, Outcome::Fail]),
            Status::ExpectedFail
        );
        assert!(Status::UnexpectedPass.is_failure() && Status::Missing.is_failure());
        assert!(!Status::Flake.is_failure() && !Status::ExpectedFail.is_failure());
    }

    #[test]
    fn a_case_listed_with_two_statuses_expects_either() {
        let x = expectations("lost-or-hung,crash\nlost-or-hung,timeout\n", "");
        for (o, want) in [
            (Outcome::Crash, Status::ExpectedFail),
            (Outcome::Timeout, Status::ExpectedFail),
            (Outcome::Fail, Status::Fail),
            (Outcome::Pass, Status::UnexpectedPass),
        ] {
            let r = report("lost-or-hung", o, None, &[]);
            assert_eq!(x.status(&r, &[o]), want, "{o:?}");
        }
        let other = report("another", Outcome::Timeout, None, &[]);
        assert_eq!(x.status(&other, &[Outcome::Timeout]), Status::Timeout);
    }

    #[test]
    fn skips_match_the_name_or_the_target_vuid() {
        let (skips, _) = parse_patterns("s", "-03686$\n^hand-");
        let x = Expectations {
            skips,
            ..Default::default()
        };
        assert!(x.skips("hand-made-valid", None));
        assert!(x.skips("x", Some("VUID-vkCmdTraceRaysIndirectKHR-stride-03686")));
        assert!(!x.skips("x", Some("VUID-vkCmdTraceRaysIndirectKHR-stride-03690")));
    }

    #[test]
    fn wildcards_match_both_trace_commands_and_nothing_else() {
        let p = "VUID-vkCmdTraceRays*KHR-None-03429";
        assert!(wildcard_match(p, "VUID-vkCmdTraceRaysKHR-None-03429"));
        assert!(wildcard_match(
            p,
            "VUID-vkCmdTraceRaysIndirectKHR-None-03429"
        ));
        assert!(!wildcard_match(p, "VUID-vkCmdTraceRaysNV-None-03429"));
        assert!(wildcard_match("VUID-x", "VUID-x"));
        assert!(!wildcard_match("VUID-x", "VUID-xy"));
    }
}
