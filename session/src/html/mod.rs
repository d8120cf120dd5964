//! The HTML report of a run folder (`rtconf report DIR`, and written by every run into
//! `DIR/report/index.html`): one static page with its pictures beside it, no external resources — the
//! summary against the baseline, the per-VUID agreement table (sortable and filterable by a small
//! inline script), and a section per case that did not pass with the model's violations, the layer's
//! messages in full, the triage that applied, the pictures of rendered cases, the case file and the
//! commands that replay and export it.

use crate::baseline::Status;
use crate::details::{read_details, CaseDetails, CASE_FOLDERS};
use crate::error::SessionError;
use crate::report::{outcome_name, Summary, VuidTally};
use crate::results::{read_lines, ResultLine};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const STYLE: &str = include_str!("report.css");
const SCRIPT: &str = include_str!("report.js");

/// The pictures a rendered case may have beside its case file, by the suffix of their name.
const PICTURES: [(&str, &str); 4] = [
    ("expected", "-expected.png"),
    ("actual", "-actual.png"),
    ("difference", "-diff.png"),
    ("difference", "-difference.png"),
];

/// One case of the report: its result line and what the run kept of it.
struct Entry {
    line: Option<ResultLine>,
    name: String,
    status: Status,
    details: Option<CaseDetails>,
    yaml: Option<(String, String)>,
    pictures: Vec<(&'static str, String)>,
}

fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + s.len() / 8);
    // The characters replaced are ASCII, so every run between them is whole UTF-8: copied at once.
    let mut plain = 0;
    for (i, b) in s.bytes().enumerate() {
        let entity = match b {
            b'&' => "&amp;",
            b'<' => "&lt;",
            b'>' => "&gt;",
            b'"' => "&quot;",
            b'\'' => "&#39;",
            _ => continue,
        };
        out.push_str(&s[plain..i]);
        out.push_str(entity);
        plain = i + 1;
    }
    out.push_str(&s[plain..]);
    out
}

/// The id of a case's section: its name with every character outside `[A-Za-z0-9_-]` replaced.
fn anchor(name: &str) -> String {
    let safe: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("case-{safe}")
}

/// Writes `out/report/index.html` (and the pictures it shows into `out/report/img/`) from the run
/// folder's `summary.json`, `results.jsonl`, details and case files; returns the page's path.
pub fn write_report(out: &Path) -> Result<PathBuf, SessionError> {
    write_report_of_folder(out).map(|(page, _)| page)
}

/// [`write_report`], and whether the run in `out` finished ([`Summary::of_folder`]: a run stopped
/// before its `summary.json` is reported from the results it has, marked unfinished).
pub fn write_report_of_folder(out: &Path) -> Result<(PathBuf, bool), SessionError> {
    let (summary, finished) = Summary::of_folder(out)?;
    let dir = out.join("report");
    let img = dir.join("img");
    std::fs::create_dir_all(&img).map_err(|e| SessionError::io(img.display().to_string(), e))?;
    let mut entries = Vec::new();
    // The files of each case folder, listed once (a run keeps thousands; probing each name a case may
    // have in every folder would be tens of thousands of lookups).
    let listed: Vec<(&str, std::collections::HashSet<std::ffi::OsString>)> = CASE_FOLDERS
        .iter()
        .map(|folder| {
            let names = std::fs::read_dir(out.join(folder))
                .map(|d| d.filter_map(|e| e.ok().map(|e| e.file_name())).collect())
                .unwrap_or_default();
            (*folder, names)
        })
        .collect();
    let mut details = read_details(out);
    for line in read_lines(&out.join("results.jsonl"))? {
        if line.status == Status::Pass && !crate::details::passed_with_warnings(&line.report) {
            continue;
        }
        let name = line.report.case.clone();
        let mut yaml = None;
        let mut pictures = Vec::new();
        for (folder, names) in &listed {
            let base = out.join(folder);
            let has = |file: &str| names.contains(std::ffi::OsStr::new(file));
            if yaml.is_none() && has(&format!("{name}.yaml")) {
                if let Ok(text) = crate::replay::case_text(&base.join(format!("{name}.yaml"))) {
                    yaml = Some((format!("{folder}/{name}.yaml"), text));
                }
            }
            for (label, suffix) in PICTURES {
                let from = base.join(format!("{name}{suffix}"));
                if has(&format!("{name}{suffix}"))
                    && from.is_file()
                    && !pictures.iter().any(|(l, _)| *l == label)
                {
                    let file = format!("{name}{suffix}");
                    std::fs::copy(&from, img.join(&file))
                        .map_err(|e| SessionError::io(from.display().to_string(), e))?;
                    pictures.push((label, format!("img/{file}")));
                }
            }
        }
        entries.push(Entry {
            details: details.remove(&name),
            status: line.status,
            line: Some(line),
            name,
            yaml,
            pictures,
        });
    }
    for m in &summary.missing {
        entries.push(Entry {
            line: None,
            name: m.clone(),
            status: Status::Missing,
            details: None,
            yaml: None,
            pictures: vec![],
        });
    }
    entries.sort_by(|a, b| (a.status, &a.name).cmp(&(b.status, &b.name)));
    let page = render(&summary, finished, &entries, &out.display().to_string());
    let path = dir.join("index.html");
    std::fs::write(&path, page).map_err(|e| SessionError::io(path.display().to_string(), e))?;
    Ok((path, finished))
}

fn render(s: &Summary, finished: bool, entries: &[Entry], run_dir: &str) -> String {
    let mut h = String::with_capacity(64 * 1024);
    let title = format!("rtconf on {} (profile {})", s.driver, s.profile);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; img-src 'self'; style-src 'unsafe-inline'; script-src 'unsafe-inline'\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>\n{STYLE}</style>\n\
         <script>\n// Errors of the page's script, kept in the page for a headless browser to read.\n\
         window.addEventListener('error', function (e) {{ var r = document.documentElement; \
         r.setAttribute('data-js-errors', (r.getAttribute('data-js-errors') || '') + (e.message || 'error') + '; '); }});\n</script>\n</head>\n<body>\n",
        escape(&title)
    );
    let _ = writeln!(h, "<header><h1>{}</h1>", escape(&title));
    let _ = writeln!(
        h,
        "<p class=\"meta\">registry {} &middot; {} cases with a result{} &middot; {:.1} s{}</p>",
        escape(s.registry.as_deref().unwrap_or("unknown")),
        s.cases,
        s.shard
            .as_deref()
            .map(|x| format!(" &middot; shard {}", escape(x)))
            .unwrap_or_default(),
        s.seconds,
        if s.expectations.is_empty() {
            " &middot; no baseline".to_string()
        } else {
            format!(" &middot; {}", escape(&s.expectations.join(", ")))
        }
    );
    h.push_str("<nav><a href=\"#summary\">Summary</a> &middot; <a href=\"#vuids\">Agreement per VUID</a> &middot; <a href=\"#cases\">Cases that did not pass</a></nav>\n</header>\n");
    summary_section(&mut h, s, finished, run_dir);
    vuid_section(&mut h, &s.vuids);
    cases_section(&mut h, entries, run_dir);
    let _ = write!(h, "<script>\n{SCRIPT}</script>\n</body>\n</html>\n");
    h
}

fn summary_section(h: &mut String, s: &Summary, finished: bool, run_dir: &str) {
    h.push_str("<section id=\"summary\"><h2>Summary</h2>\n");
    let verdict = if !finished {
        format!(
            "<p><span class=\"badge s-fail\" id=\"run-verdict\">unfinished</span> {}; the {} cases with a result are counted below.</p>\n",
            escape(&crate::report::unfinished_run(Path::new(run_dir))),
            s.cases
        )
    } else if s.unexpected() == 0 {
        "<p><span class=\"badge s-pass\" id=\"run-verdict\">as expected</span> no case has a status that fails the run.</p>\n".to_string()
    } else {
        format!(
            "<p><span class=\"badge s-fail\" id=\"run-verdict\">unexpected results</span> {} case(s) have a status that fails the run (fail, crash, timeout, unexpected-pass, missing).</p>\n",
            s.unexpected()
        )
    };
    h.push_str(&verdict);
    h.push_str("<h4>Status against the baseline</h4>\n<table class=\"counts\" id=\"status-counts\"><thead><tr><th>status</th><th class=\"n\">cases</th><th>meaning</th></tr></thead><tbody>\n");
    for st in Status::ALL {
        let n = s.count(st);
        let listed = if st == Status::Pass {
            String::new()
        } else {
            format!(" data-listed-status=\"{}\"", st.name())
        };
        let _ = writeln!(
            h,
            "<tr><td><span class=\"badge s-{0}\">{0}</span></td><td class=\"n\" id=\"status-{0}\"{listed}>{n}</td><td>{1}</td></tr>",
            st.name(),
            escape(st.meaning())
        );
    }
    h.push_str("</tbody></table>\n");
    h.push_str("<h4>Raw outcomes</h4>\n<table class=\"counts\" id=\"outcome-counts\"><tbody>\n");
    for (name, n) in [
        ("pass", s.passed),
        ("fail", s.failed),
        ("triaged", s.triaged),
        ("unsupported", s.unsupported),
        ("crash", s.crashes),
        ("timeout", s.timeouts),
    ] {
        let _ = writeln!(
            h,
            "<tr><td>{name}</td><td class=\"n\" id=\"outcome-{name}\">{n}</td></tr>"
        );
    }
    let _ = writeln!(
        h,
        "<tr><td>cases</td><td class=\"n\" id=\"outcome-cases\">{}</td></tr>\n</tbody></table>",
        s.cases
    );
    let _ = writeln!(
        h,
        "<p class=\"meta\">The raw outcome compares the model with the driver and the layer; the status judges it against the baseline, skips and flakes files. {} case(s) were kept from running by the skips list; failing cases were run again {} time(s) in all to tell flakes.</p>\n</section>",
        s.skipped, s.retries
    );
}

fn vuid_section(h: &mut String, vuids: &std::collections::BTreeMap<String, VuidTally>) {
    h.push_str("<section id=\"vuids\"><h2>Agreement per VUID</h2>\n<dl class=\"legend\">\n\
        <dt>cases</dt><dd>cases that ran (unsupported, crashed and timed-out ones left out) in which the model or the layer named the VUID</dd>\n\
        <dt>model</dt><dd>of those, the cases in which the model says the call violates it</dd>\n\
        <dt>layer</dt><dd>of those, the cases in which the validation layer reported it</dd>\n\
        <dt>agree</dt><dd>of those, the cases in which both named it</dd>\n\
        <dt>agreement</dt><dd>agree / cases; a disagreement is a failure unless triage/ explains it</dd>\n</dl>\n");
    let _ = writeln!(
        h,
        "<div class=\"controls\"><label>Filter <input id=\"vuid-table-filter\" type=\"search\" placeholder=\"VUID or words\"></label> <span><span id=\"vuid-table-shown\">{}</span> of {} shown</span></div>",
        vuids.len(),
        vuids.len()
    );
    h.push_str("<table id=\"vuid-table\"><thead><tr><th data-sort=\"text\">VUID</th><th class=\"n\" data-sort=\"num\">cases</th><th class=\"n\" data-sort=\"num\">model</th><th class=\"n\" data-sort=\"num\">layer</th><th class=\"n\" data-sort=\"num\">agree</th><th class=\"n\" data-sort=\"num\">agreement</th></tr></thead><tbody>\n");
    for (v, t) in vuids {
        let rate = if t.cases == 0 {
            0.0
        } else {
            t.agree as f64 / t.cases as f64
        };
        let _ = writeln!(
            h,
            "<tr><td><code>{}</code></td><td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\">{}</td><td class=\"n\" data-value=\"{rate:.4}\"><span class=\"bar{}\" style=\"width:{:.0}px\"></span> {:.0}%</td></tr>",
            escape(v),
            t.cases,
            t.model,
            t.layer,
            t.agree,
            if rate < 1.0 { " low" } else { "" },
            rate * 40.0,
            rate * 100.0
        );
    }
    h.push_str("</tbody></table>\n</section>\n");
}

fn cases_section(h: &mut String, entries: &[Entry], run_dir: &str) {
    h.push_str("<section id=\"cases\"><h2>Cases that did not pass</h2>\n");
    let _ = writeln!(
        h,
        "<div class=\"controls\"><label>Filter <input id=\"case-table-filter\" type=\"search\" placeholder=\"name, VUID, words\"></label> <label>Status <select id=\"case-table-status\"><option value=\"\">any</option>{}</select></label> <span><span id=\"case-table-shown\">{}</span> of {} shown</span></div>",
        Status::ALL
            .iter()
            .filter(|s| **s != Status::Pass)
            .map(|s| format!("<option>{}</option>", s.name()))
            .collect::<String>(),
        entries.len(),
        entries.len()
    );
    h.push_str("<table id=\"case-table\"><thead><tr><th data-sort=\"text\">case</th><th data-sort=\"text\">status</th><th data-sort=\"text\">outcome</th><th data-sort=\"text\">command</th><th data-sort=\"text\">target</th><th>what happened</th></tr></thead><tbody>\n");
    for e in entries {
        let (outcome, command, target, detail) = match &e.line {
            Some(l) => (
                outcome_name(l.report.outcome),
                l.report.command.vk_name(),
                l.report.target.clone().unwrap_or_else(|| "valid".into()),
                l.report.detail.clone(),
            ),
            None => ("-", "-", "-".into(), "planned, no result".into()),
        };
        let short: String = detail.chars().take(160).collect();
        let _ = writeln!(
            h,
            "<tr data-status=\"{st}\"><td><a href=\"#{}\">{}</a></td><td><span class=\"badge s-{st}\">{st}</span></td><td>{outcome}</td><td>{command}</td><td><code>{}</code></td><td title=\"{}\">{}{}</td></tr>",
            anchor(&e.name),
            escape(&e.name),
            escape(&target),
            escape(&detail),
            escape(&short),
            if short.len() < detail.len() { "…" } else { "" },
            st = e.status.name(),
        );
    }
    h.push_str("</tbody></table>\n");
    for e in entries {
        case_article(h, e, run_dir);
    }
    h.push_str("</section>\n");
}

fn case_article(h: &mut String, e: &Entry, run_dir: &str) {
    let st = e.status.name();
    let _ = writeln!(
        h,
        "<article class=\"case\" id=\"{}\" data-status=\"{st}\"><h3>{} <span class=\"badge s-{st}\">{st}</span></h3>",
        anchor(&e.name),
        escape(&e.name)
    );
    let Some(line) = &e.line else {
        h.push_str("<p>The case was in the run's case list (<code>caselist.txt</code>) but no result came back: its shard or worker stopped before it.</p>\n</article>\n");
        return;
    };
    let r = &line.report;
    h.push_str("<dl>\n");
    let mut row = |k: &str, v: String| {
        let _ = writeln!(h, "<dt>{k}</dt><dd>{v}</dd>");
    };
    row("command", format!("<code>{}</code>", r.command.vk_name()));
    row(
        "intent",
        match &r.target {
            Some(t) => format!("violates <code>{}</code>", escape(t)),
            None => "valid (run for real, output compared)".into(),
        },
    );
    row("raw outcome", outcome_name(r.outcome).into());
    if line.attempts.len() > 1 {
        row(
            "attempts",
            line.attempts
                .iter()
                .map(|o| outcome_name(*o))
                .collect::<Vec<_>>()
                .join(", "),
        );
    }
    let list = |v: &[String]| {
        if v.is_empty() {
            "nothing".to_string()
        } else {
            v.iter()
                .map(|x| format!("<code>{}</code>", escape(x)))
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    row("model", list(&r.model));
    row("layer", list(&r.layer));
    if !r.layer_other.is_empty() {
        row("layer, other scopes", list(&r.layer_other));
    }
    if let Some(ok) = r.output_matches {
        row(
            "output",
            if ok {
                "matches the model".into()
            } else {
                "<strong>differs from the model</strong>".into()
            },
        );
    }
    row("time", format!("{:.1} ms", r.millis));
    h.push_str("</dl>\n");
    if !r.detail.is_empty() {
        let _ = writeln!(h, "<h4>What happened</h4><pre>{}</pre>", escape(&r.detail));
    }
    if let Some(d) = &e.details {
        if !d.violations.is_empty() {
            h.push_str("<h4>The model's violations</h4><table><thead><tr><th>VUID</th><th>where</th><th>problem</th></tr></thead><tbody>\n");
            for v in &d.violations {
                let _ = writeln!(
                    h,
                    "<tr><td><code>{}</code></td><td><code>{}</code></td><td>{}</td></tr>",
                    escape(&v.vuid),
                    escape(&v.context),
                    escape(&v.problem)
                );
            }
            h.push_str("</tbody></table>\n");
        }
        if !d.layer_messages.is_empty() {
            h.push_str("<h4>The layer's messages</h4>\n");
            for m in &d.layer_messages {
                let _ = writeln!(
                    h,
                    "<pre>[{}] {}\n{}</pre>",
                    escape(&m.severity),
                    escape(&m.id),
                    escape(&m.text)
                );
            }
        }
    }
    if !line.triage.is_empty() {
        h.push_str("<h4>Triage that applied</h4><table><thead><tr><th>key</th><th>side</th><th>kind</th><th>reason</th></tr></thead><tbody>\n");
        for t in &line.triage {
            let _ = writeln!(
                h,
                "<tr><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}{}</td></tr>",
                escape(&t.key),
                escape(&t.side),
                escape(&t.kind),
                escape(&t.reason),
                t.case
                    .as_deref()
                    .map(|c| format!(" (reproduced by <code>{}</code>)", escape(c)))
                    .unwrap_or_default()
            );
        }
        h.push_str("</tbody></table>\n");
    }
    if !e.pictures.is_empty() {
        h.push_str("<h4>Pictures</h4><div class=\"pictures\">");
        for (label, src) in &e.pictures {
            let _ = write!(
                h,
                "<figure><img src=\"{}\" alt=\"{label} picture of {}\"><figcaption>{label}</figcaption></figure>",
                escape(src),
                escape(&e.name)
            );
        }
        h.push_str("</div>\n");
    }
    if let Some((rel, text)) = &e.yaml {
        let path = format!("{}/{rel}", run_dir.trim_end_matches('/'));
        let _ = writeln!(
            h,
            "<h4>Reproduce</h4><pre>rtconf replay {0}\nrtconf export {0} --out repro-{1}   # a standalone C program</pre>",
            escape(&path),
            escape(&e.name)
        );
        let _ = writeln!(
            h,
            "<details><summary>The case file (<a href=\"../{}\">{}</a>)</summary><pre>{}</pre></details>",
            escape(rel),
            escape(rel),
            escape(text)
        );
    } else if let Some(folder) = e
        .line
        .as_ref()
        .and_then(|l| crate::details::kept_folder(&l.report, l.status))
        .filter(|f| !crate::details::keeps_file(f, false))
    {
        let _ = writeln!(
            h,
            "<p>The case file was not kept: its outcome is explained ({folder}). A run with <code>--keep-all</code> keeps it.</p>"
        );
    }
    h.push_str("</article>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_and_anchors_are_safe() {
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        // Text around and between the replaced characters is kept whole, multi-byte characters too.
        assert_eq!(escape("Y′CbCr <é> ≤ 2"), "Y′CbCr &lt;é&gt; ≤ 2");
        assert_eq!(escape("plain"), "plain");
        assert_eq!(escape(""), "");
        assert_eq!(anchor("a b/c<d>"), "case-a_b_c_d_");
    }
}
