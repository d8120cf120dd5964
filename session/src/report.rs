//! What a run leaves besides `results.jsonl`: the per-VUID agreement table and totals of
//! `summary.json`, and the JUnit report, both read back from `results.jsonl` a line at a time.

use crate::compare::{CaseReport, Outcome};
use crate::error::SessionError;
use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, Write};
use std::path::Path;

/// Per-VUID agreement counts of `summary.json`.
#[derive(Debug, Default, serde::Serialize)]
pub struct VuidTally {
    pub cases: usize,
    pub model: usize,
    pub layer: usize,
    pub agree: usize,
}

/// `summary.json`.
#[derive(Debug, Default, serde::Serialize)]
pub struct Summary {
    pub driver: String,
    pub profile: String,
    pub registry: Option<String>,
    pub cases: usize,
    pub passed: usize,
    pub failed: usize,
    pub triaged: usize,
    pub unsupported: usize,
    pub crashes: usize,
    pub timeouts: usize,
    /// Cases at fault themselves (`case-error`): not run, or disagreeing with the model about their intent.
    pub case_errors: usize,
    /// Peak resident memory of the runner process itself (workers excluded), in KiB (Linux).
    pub runner_peak_rss_kib: Option<u64>,
    /// Wall time of the run, in seconds.
    pub seconds: f64,
    pub vuids: BTreeMap<String, VuidTally>,
    /// Per trace command: the rendered output judged per ray (counts, VARY share, error quantiles).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub rendered: BTreeMap<String, crate::rendered::RenderedTotals>,
}

/// The reports of `results.jsonl`, read one line at a time.
pub(crate) fn reports(path: &Path) -> Result<impl Iterator<Item = CaseReport>, SessionError> {
    let f =
        std::fs::File::open(path).map_err(|e| SessionError::io(path.display().to_string(), e))?;
    Ok(std::io::BufReader::new(f)
        .lines()
        .map_while(Result::ok)
        .filter_map(|l| serde_json::from_str::<CaseReport>(&l).ok()))
}

/// Reads `results.jsonl` back, streaming, into the summary; a resumed run never runs a case twice, so
/// each line is one case. Memory is per VUID, not per case.
pub(crate) fn summarise(
    path: &Path,
    driver: &str,
    profile: &str,
    registry: Option<String>,
) -> Result<Summary, SessionError> {
    let mut s = Summary {
        driver: driver.into(),
        profile: profile.into(),
        registry,
        ..Default::default()
    };
    for r in reports(path)? {
        s.cases += 1;
        if let Some(x) = &r.rendered {
            s.rendered
                .entry(r.command.vk_name().to_string())
                .or_default()
                .add(x);
        }
        match r.outcome {
            Outcome::Pass => s.passed += 1,
            Outcome::Fail => s.failed += 1,
            Outcome::Triaged => s.triaged += 1,
            Outcome::Unsupported => s.unsupported += 1,
            Outcome::Crash => s.crashes += 1,
            Outcome::Timeout => s.timeouts += 1,
            Outcome::CaseError => s.case_errors += 1,
        }
        if matches!(
            r.outcome,
            Outcome::Unsupported | Outcome::Crash | Outcome::Timeout | Outcome::CaseError
        ) {
            continue;
        }
        let m: BTreeSet<&String> = r.model.iter().collect();
        let l: BTreeSet<&String> = r.layer.iter().collect();
        for v in m.union(&l) {
            let t = s.vuids.entry((*v).clone()).or_default();
            t.cases += 1;
            t.model += m.contains(v) as usize;
            t.layer += l.contains(v) as usize;
            t.agree += (m.contains(v) == l.contains(v)) as usize;
        }
    }
    Ok(s)
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Writes the JUnit report (one suite for the run; triaged cases pass, unsupported ones are skipped),
/// streaming from `results.jsonl` so memory does not grow with the run.
pub(crate) fn write_junit(results: &Path, out: &Path, s: &Summary) -> Result<(), SessionError> {
    let io = |e: std::io::Error| SessionError::io(out.display().to_string(), e);
    let mut w = std::io::BufWriter::new(std::fs::File::create(out).map_err(io)?);
    let name = xml_escape(&format!("rtconf on {}", s.driver));
    let errors = s.crashes + s.timeouts + s.case_errors;
    let head = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"{name}\" tests=\"{}\" failures=\"{}\" errors=\"{errors}\">\n  <testsuite name=\"{name}\" tests=\"{}\" failures=\"{}\" errors=\"{errors}\" skipped=\"{}\">\n",
        s.cases, s.failed, s.cases, s.failed, s.unsupported
    );
    w.write_all(head.as_bytes()).map_err(io)?;
    for r in reports(results)? {
        let open = format!(
            "    <testcase name=\"{}\" classname=\"{}.{}\" time=\"{:.3}\"",
            xml_escape(&r.case),
            xml_escape(&s.driver),
            xml_escape(r.command.vk_name()),
            r.millis.max(0.0) / 1000.0
        );
        let msg = xml_escape(&r.detail);
        let body = match r.outcome {
            Outcome::Pass | Outcome::Triaged => "/>\n".to_string(),
            Outcome::Unsupported => format!("><skipped message=\"{msg}\"/></testcase>\n"),
            Outcome::Fail => format!("><failure message=\"{msg}\"/></testcase>\n"),
            Outcome::Crash | Outcome::Timeout | Outcome::CaseError => {
                format!("><error message=\"{:?}: {msg}\"/></testcase>\n", r.outcome)
            }
        };
        w.write_all(open.as_bytes())
            .and_then(|_| w.write_all(body.as_bytes()))
            .map_err(io)?;
    }
    w.write_all(b"  </testsuite>\n</testsuites>\n")
        .and_then(|_| w.flush())
        .map_err(io)
}
