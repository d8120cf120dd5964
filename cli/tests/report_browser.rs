//! The HTML report in a real headless browser (Debian's chromium): a run on lavapipe with a passing, a
//! triaged, an unsupported, a crashing case with pictures beside it and an unexpected pass; the page
//! loads without a console message or script error, its sort and filter work (its own self-test, run
//! with `#selftest`), the counts it shows equal summary.json, every picture loads, each case that did
//! not pass has its section (violations, the layer's messages in full, triage, replay command), and a
//! screenshot is kept in `target/tmp/report-browser/`.

#[path = "common/folders.rs"]
mod common;

use common::{case_as, fresh_dir, rtconf, summary, text};
use std::path::Path;
use std::process::{Command, Output};

/// A 2x2 RGB PNG (red and blue columns), for pictures beside a failing case.
const PNG_2X2: &[u8] = &[
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
    0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x02, 0x00, 0x00, 0x00, 0xfd, 0xd4, 0x9a,
    0x73, 0x00, 0x00, 0x00, 0x10, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xf8, 0xcf, 0x00, 0x04,
    0xff, 0x19, 0x20, 0x14, 0x00, 0x1b, 0xf2, 0x03, 0xfd, 0xd6, 0x96, 0xf2, 0x2b, 0x00, 0x00, 0x00,
    0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82,
];

/// Headless chromium with the flags that keep it off the network and out of the user's profile.
fn chromium(profile: &Path, args: &[&str]) -> Output {
    Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            &format!("--user-data-dir={}", profile.display()),
        ])
        .args(args)
        .output()
        .expect("chromium runs (it is installed by `bash scripts/setup.sh`)")
}

/// The number in the element with `id` (`<td … id="status-fail" …>3</td>`).
fn number_at(dom: &str, id: &str) -> u64 {
    let at = dom
        .find(&format!("id=\"{id}\""))
        .unwrap_or_else(|| panic!("no element #{id}"));
    let rest = &dom[at..];
    let start = rest.find('>').unwrap() + 1;
    let end = rest[start..].find('<').unwrap() + start;
    rest[start..end]
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("#{id} holds `{}`", &rest[start..end]))
}

/// The value of an attribute of the root element.
fn root_attribute<'a>(dom: &'a str, name: &str) -> Option<&'a str> {
    let html = &dom[dom.find("<html")?..];
    let html = &html[..html.find('>')?];
    let at = html.find(&format!(" {name}=\""))? + name.len() + 3;
    Some(&html[at..at + html[at..].find('"')?])
}

/// Text as the browser serialises a text node.
fn as_text_node(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[test]
fn the_report_loads_in_chromium_and_shows_the_summary_counts() {
    let dir = fresh_dir("report-browser");
    let cases = dir.join("cases");
    std::fs::create_dir_all(&cases).unwrap();
    case_as(
        "hand/trace-indirect-records-32.yaml",
        "hand-made-valid",
        &cases,
    );
    case_as(
        "hand/trace-indirect-records-32.yaml",
        "fault-abort-pictured",
        &cases,
    );
    case_as(
        "hand/trace-indirect-miss-stride-unaligned.yaml",
        "stride-expected-to-fail",
        &cases,
    );
    for vuid in [
        // triaged: a layer gap
        "VUID-vkCmdTraceRaysIndirectKHR-None-02702",
        // not realised: an indirect buffer with no memory bound (its address query is itself invalid)
        "VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03632",
    ] {
        let g = rtconf(
            &[
                "gen",
                "--vuid",
                vuid,
                "--count",
                "1",
                "--out",
                cases.to_str().unwrap(),
            ],
            &[],
        );
        assert!(g.status.success(), "{}", text(&g));
    }
    let baseline = dir.join("baseline.txt");
    std::fs::write(&baseline, "stride-expected-to-fail,fail\n").unwrap();
    let run = dir.join("run");
    let o = rtconf(
        &[
            "run",
            "--cases",
            cases.to_str().unwrap(),
            "--baseline",
            baseline.to_str().unwrap(),
            "--out",
            run.to_str().unwrap(),
        ],
        &[(harness::worker::FAULTS_ENV, "1")],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    // Pictures beside the failing case, as a rendered case leaves them; the report is written again.
    for suffix in ["expected", "actual", "diff"] {
        std::fs::write(
            run.join("failures")
                .join(format!("fault-abort-pictured-{suffix}.png")),
            PNG_2X2,
        )
        .unwrap();
    }
    let o = rtconf(&["report", run.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", text(&o));
    let page = run.join("report/index.html");
    assert_eq!(
        String::from_utf8_lossy(&o.stdout).trim(),
        page.display().to_string()
    );
    let html = std::fs::read_to_string(&page).unwrap();
    // Every address the page loads or links is inside the run folder.
    for attr in ["src=\"", "href=\""] {
        for (at, _) in html.match_indices(attr) {
            let value = &html[at + attr.len()..];
            let value = &value[..value.find('"').unwrap()];
            assert!(
                value.starts_with('#') || value.starts_with("img/") || value.starts_with("../"),
                "the page names {value}"
            );
        }
    }
    assert!(
        !html.contains("<link") && !html.contains("url("),
        "no stylesheet or font is fetched"
    );

    let profile = dir.join("chromium-profile");
    let url = format!("file://{}#selftest", page.display());
    let loaded = chromium(
        &profile,
        &["--enable-logging=stderr", "--v=0", "--dump-dom", &url],
    );
    assert!(loaded.status.success(), "{}", text(&loaded));
    let dom = String::from_utf8_lossy(&loaded.stdout).into_owned();
    std::fs::write(dir.join("dom.html"), &dom).unwrap();
    let log = String::from_utf8_lossy(&loaded.stderr);
    let console: Vec<&str> = log.lines().filter(|l| l.contains(":CONSOLE")).collect();
    assert!(console.is_empty(), "console messages: {console:#?}");
    assert_eq!(root_attribute(&dom, "data-js-errors"), None, "{dom}");
    assert_eq!(root_attribute(&dom, "data-ready"), Some("1"));
    assert_eq!(root_attribute(&dom, "data-selftest"), Some("ok"));
    assert_eq!(root_attribute(&dom, "data-consistent"), Some("yes"));
    assert_eq!(root_attribute(&dom, "data-images"), Some("3/3"));

    // The counts shown are summary.json's.
    let s = summary(&run);
    for (name, n) in s["statuses"].as_object().unwrap() {
        assert_eq!(
            number_at(&dom, &format!("status-{name}")),
            n.as_u64().unwrap(),
            "status {name}"
        );
    }
    for (id, key) in [
        ("outcome-pass", "passed"),
        ("outcome-fail", "failed"),
        ("outcome-triaged", "triaged"),
        ("outcome-unsupported", "unsupported"),
        ("outcome-crash", "crashes"),
        ("outcome-timeout", "timeouts"),
        ("outcome-cases", "cases"),
    ] {
        assert_eq!(number_at(&dom, id), s[key].as_u64().unwrap(), "{id}");
    }
    for st in ["triaged", "skip", "crash", "unexpected-pass"] {
        assert_eq!(s["statuses"][st], 1, "{st}: {s}");
    }
    let vuid_rows = {
        let t = &dom[dom.find("id=\"vuid-table\"").unwrap()..];
        let t = &t[t.find("<tbody>").unwrap()..t.find("</tbody>").unwrap()];
        t.matches("<tr").count()
    };
    assert_eq!(vuid_rows, s["vuids"].as_object().unwrap().len());

    // A section per case that did not pass, with what a bug report needs.
    let section = |name: &str| -> String {
        let start = dom
            .find(&format!("<article class=\"case\" id=\"case-{name}\""))
            .unwrap_or_else(|| panic!("no section for {name}"));
        let rest = &dom[start..];
        rest[..rest.find("</article>").unwrap()].to_string()
    };
    let triaged = section("vkCmdTraceRaysIndirectKHR-None-02702-1-0");
    assert!(triaged.contains("Triage that applied"), "{triaged}");
    assert!(triaged.contains("layer-gap"), "{triaged}");
    assert!(triaged.contains("The model's violations"), "{triaged}");
    // Its outcome is explained: its case file is not kept, and the section says how to keep it.
    assert!(!triaged.contains("rtconf replay"), "{triaged}");
    assert!(triaged.contains("--keep-all"), "{triaged}");
    let crash = section("fault-abort-pictured");
    assert!(
        crash.contains(&format!(
            "rtconf replay {}/failures/fault-abort-pictured.yaml",
            run.display()
        )),
        "{crash}"
    );
    assert!(
        crash.contains("img/fault-abort-pictured-diff.png"),
        "{crash}"
    );
    let unexpected = section("stride-expected-to-fail");
    let details: serde_json::Value = std::fs::read_to_string(run.join("details.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|d| d["case"] == "stride-expected-to-fail")
        .expect("the case's details line");
    let message = details["layer_messages"][0]["text"].as_str().unwrap();
    assert!(message.len() > 300, "a message worth checking in full");
    assert!(
        unexpected.contains(&as_text_node(message)),
        "the layer's message in full: {unexpected}"
    );
    let not_realised = section("vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03632-1-0");
    assert!(not_realised.contains("no memory bound"), "{not_realised}");
    assert!(
        !dom.contains("id=\"case-hand-made-valid\""),
        "passing cases have no section"
    );

    // A screenshot, kept as the test's artifact.
    let shot = dir.join("report.png");
    let o = chromium(
        &profile,
        &[
            &format!("--screenshot={}", shot.display()),
            "--window-size=1280,2400",
            &format!("file://{}", page.display()),
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let png = std::fs::read(&shot).expect("the screenshot");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 20_000,
        "{} bytes",
        png.len()
    );
}
