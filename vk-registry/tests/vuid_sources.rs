//! validusage.json (both schemas) and man pages (three formats) on hand-written fixtures,
//! source loading, unions, reports, and located errors for mangled inputs.

mod common;

use std::path::PathBuf;
use vk_registry::error::Location;
use vk_registry::manpage::{self, ManPageFormat};
use vk_registry::{
    load_union, load_vuids, report, validusage, Condition, RegistryError, ScopeKind, VuidSet,
};

fn old_schema() -> VuidSet {
    load_vuids(&common::fixture("validusage_1_3.json")).unwrap()
}

fn new_schema() -> VuidSet {
    load_vuids(&common::fixture("validusage_1_4.json")).unwrap()
}

#[test]
fn old_schema_with_condition_keys() {
    let s = old_schema();
    assert_eq!(s.version.as_deref(), Some("1.3.999"));
    assert_eq!(
        s.ids(),
        [
            "VUID-VkToyRegion-stride-00003",
            "VUID-vkCmdToyDispatch-commandBuffer-parameter",
            "VUID-vkCmdToyDispatch-pRegion-00002",
            "VUID-vkCmdToyDispatch-renderpass",
            "VUID-vkCmdToyDispatch-stride-00001",
        ]
    );
    let r = s.get("VUID-vkCmdToyDispatch-pRegion-00002").unwrap();
    assert_eq!(
        r.condition.to_string(),
        "VK_KHR_toy_dispatch+!(VK_VERSION_1_3,VK_KHR_toy_extra)"
    );
    assert!(r.condition.eval(&|n| n == "VK_KHR_toy_dispatch"));
    assert!(!r
        .condition
        .eval(&|n| n == "VK_KHR_toy_dispatch" || n == "VK_VERSION_1_3"));
    assert_eq!(
        (
            r.scope.as_str(),
            r.scope_kind,
            r.field.as_str(),
            r.tag.as_str(),
            r.implicit
        ),
        (
            "vkCmdToyDispatch",
            ScopeKind::Command,
            "pRegion",
            "00002",
            false
        )
    );
    assert_eq!(
        r.text,
        "If the `toyFeature` feature is not enabled, `pRegion` must not be `NULL`"
    );
    let rp = s.get("VUID-vkCmdToyDispatch-renderpass").unwrap();
    assert_eq!(
        (
            rp.field.as_str(),
            rp.tag.as_str(),
            rp.implicit,
            &rp.condition
        ),
        ("None", "renderpass", true, &Condition::Always)
    );
    let st = s.get("VUID-vkCmdToyDispatch-stride-00001").unwrap();
    assert_eq!(
        st.text,
        "`pRegion->stride` must be a multiple of the toy’s `toyAlign`"
    );
    assert_eq!(st.condition, Condition::Ext("VK_KHR_toy_dispatch".into()));
    let sr = s.get("VUID-VkToyRegion-stride-00003").unwrap();
    assert_eq!(
        (sr.scope_kind, sr.text.as_str()),
        (ScopeKind::Structure, "`stride` must be less than `2`32")
    );
}

#[test]
fn new_schema_with_core_and_pages() {
    let s = new_schema();
    assert_eq!(s.version.as_deref(), Some("1.4.999"));
    assert_eq!(s.len(), 4);
    assert!(s.records.iter().all(|r| r.condition == Condition::Always));
    assert_eq!(
        s.get("VUID-vkCmdToyDispatch-pRegion-00004").unwrap().text,
        "`pRegion` must be aligned"
    );
}

#[test]
fn man_page_formats_agree() {
    let json = old_schema();
    let mut texts = Vec::new();
    for (file, format) in [
        ("toy_html.md", ManPageFormat::HtmlMarkdown),
        ("toy_pandoc.md", ManPageFormat::PandocMarkdown),
        ("toy_plain.txt", ManPageFormat::PlainText),
    ] {
        let text = common::fixture_text(file);
        assert_eq!(manpage::detect_format(&text), Some(format), "{file}");
        let (page, set) = manpage::parse(&text, file).unwrap();
        assert_eq!(page.command, "vkCmdToyDispatch", "{file}");
        assert_eq!(
            page.prototype,
            "void vkCmdToyDispatch(VkToyBuffer commandBuffer, const VkToyRegion* pRegion, uint32_t* pCount);",
            "{file}"
        );
        // referenced VUIDs are not definitions
        assert_eq!(
            set.ids(),
            [
                "VUID-vkCmdToyDispatch-commandBuffer-parameter",
                "VUID-vkCmdToyDispatch-pRegion-00002",
                "VUID-vkCmdToyDispatch-renderpass",
                "VUID-vkCmdToyDispatch-stride-00001",
            ],
            "{file}"
        );
        assert!(set.records.iter().all(|r| r.condition == Condition::Always));
        texts.push(
            set.records
                .iter()
                .map(|r| r.text.clone())
                .collect::<Vec<_>>(),
        );
        if format != ManPageFormat::PlainText {
            for r in &set.records {
                if r.id != "VUID-vkCmdToyDispatch-pRegion-00002" {
                    assert_eq!(
                        Some(&r.text),
                        json.get(&r.id).map(|j| &j.text),
                        "{file} {}",
                        r.id
                    );
                }
            }
        }
    }
    assert_eq!(
        texts[0], texts[1],
        "the two Markdown formats normalise identically"
    );
    assert_eq!(
        texts[2][0],
        "commandBuffer must be a valid VkToyBuffer handle"
    );
}

#[test]
fn truncated_man_pages_give_located_errors() {
    let text = common::fixture_text("toy_pandoc.md");
    // cut inside an anchor
    let cut = text
        .find("id=\"VUID-vkCmdToyDispatch-pRegion-00002\"")
        .unwrap()
        + 10;
    let e = manpage::parse(&text[..cut], "toy_pandoc.md").unwrap_err();
    let line = text[..cut]
        .lines()
        .position(|l| l.contains("href=\"#VUID-vkCmdToyDispatch-pRegion-00002\""))
        .unwrap()
        + 1;
    assert_eq!(
        e.location(),
        Some(&Location::LineCol { line, column: 3 }),
        "{e}"
    );
    assert!(e.to_string().contains("truncated"), "{e}");
    // cut inside the prototype
    let cut = text.find("pRegion,").unwrap();
    let e = manpage::parse(&text[..cut], "toy_pandoc.md").unwrap_err();
    assert!(
        e.to_string().contains("no VUID") || e.to_string().contains("prototype"),
        "{e}"
    );
    // cut right after a VUID line (no text)
    let html = common::fixture_text("toy_html.md");
    let cut = html.find("VUID-vkCmdToyDispatch-renderpass  \n").unwrap()
        + "VUID-vkCmdToyDispatch-renderpass  \n".len();
    let e = manpage::parse(&html[..cut], "toy_html.md").unwrap_err();
    assert!(e.to_string().contains("has no text"), "{e}");
    assert!(matches!(e.location(), Some(Location::LineCol { .. })));
    // any cut point: an error or a smaller set, never a panic
    for file in ["toy_html.md", "toy_pandoc.md", "toy_plain.txt"] {
        let text = common::fixture_text(file);
        let mut ok = 0;
        for cut in (0..text.len()).filter(|c| text.is_char_boundary(*c)) {
            match manpage::parse(&text[..cut], file) {
                Ok((_, set)) => {
                    assert!(set.len() <= 4);
                    ok += 1;
                }
                Err(e) => assert!(e.location().is_some(), "{file} cut {cut}: {e}"),
            }
        }
        assert!(ok > 0, "{file}: some prefixes are whole pages");
    }
}

#[test]
fn prototypes_are_found_past_long_prose_lines_and_conditions_too_deep_are_located() {
    let html = common::fixture_text("toy_html.md");
    let (want, _) = manpage::parse(&html, "toy_html.md").unwrap();
    // a prose line mentioning the command many times, before the prototype
    let prose = "word ".repeat(40) + &"vkCmdToyDispatch( ".repeat(20_000) + "\n";
    let at = html.find("```c++").unwrap();
    let text = format!("{}{prose}{}", &html[..at], &html[at..]);
    let (page, _) = manpage::parse(&text, "long-prose.md").unwrap();
    assert_eq!(page.prototype, want.prototype);
    assert!(
        page.prototype.starts_with("void vkCmdToyDispatch("),
        "{}",
        page.prototype
    );
    // a condition key nested far too deep is refused at its JSON path, the key shortened
    let key = format!("{}VK_KHR_a{}", "(".repeat(20_000), ")".repeat(20_000));
    let json = format!(
        r#"{{"validation":{{"vkCmdX":{{"{key}":[{{"vuid":"VUID-vkCmdX-a-1","text":"t"}}]}}}}}}"#
    );
    let e = validusage::parse(&json, "deep.json").unwrap_err();
    assert_eq!(
        e.location(),
        Some(&Location::JsonPath("$.validation.vkCmdX".into()))
    );
    assert!(e.to_string().contains("deeper than"), "{e}");
    assert!(e.to_string().len() < 300, "{e}");
}

/// A cut in the middle of the document's JSON.
fn cut_json(text: &str) -> usize {
    text.len() / 2
}

#[test]
fn garbled_json_gives_line_column_or_json_path() {
    let text = common::fixture_text("validusage_1_3.json");
    // truncated
    let cut = text.find("\"(VK_KHR_toy_dispatch)\"").unwrap() + 5;
    let e = validusage::parse(&text[..cut], "v.json").unwrap_err();
    let line = text[..cut].lines().count();
    match e.location() {
        Some(Location::LineCol { line: l, .. }) => assert_eq!(*l, line, "{e}"),
        other => panic!("expected line:column, got {other:?}"),
    }
    // syntax error in the middle
    let bad = text.replacen("\"text\":", "\"text\" ", 1);
    let e = validusage::parse(&bad, "v.json").unwrap_err();
    assert!(
        matches!(
            e.location(),
            Some(Location::LineCol {
                line: 13,
                column: 19
            })
        ),
        "{e}"
    );
    // wrong shape: a number where a text belongs
    let bad = text.replacen(
        "\"text\": \"This command",
        "\"text\": 7, \"x\": \"This command",
        1,
    );
    let e = validusage::parse(&bad, "v.json").unwrap_err();
    match e.location() {
        Some(Location::JsonPathAt { path, .. }) => {
            assert_eq!(path, "$.validation.vkCmdToyDispatch.core[1].text", "{e}")
        }
        other => panic!("expected a JSON path, got {other:?}"),
    }
    // not a VUID
    let bad = text.replacen("VUID-VkToyRegion-stride-00003", "NOT-A-VUID", 1);
    let e = validusage::parse(&bad, "v.json").unwrap_err();
    assert_eq!(
        e.location(),
        Some(&Location::JsonPath(
            "$.validation.VkToyRegion.core[0].vuid".into()
        )),
        "{e}"
    );
    // bad condition key
    let bad = text.replacen("\"(VK_KHR_toy_dispatch)\"", "\"(VK_KHR_toy_dispatch\"", 1);
    let e = validusage::parse(&bad, "v.json").unwrap_err();
    assert!(
        e.to_string().contains("$.validation.vkCmdToyDispatch"),
        "{e}"
    );
    // ... read only where its scope is kept: another scope's reading does not see it, and the
    // JSON itself is still read whole
    let others = |s: &str| s != "vkCmdToyDispatch";
    let set = validusage::parse_where(&bad, "v.json", &others).expect("the other scopes read");
    assert!(!set.records.is_empty());
    assert!(set.records.iter().all(|r| others(&r.scope)));
    assert!(validusage::parse_where(&bad, "v.json", &|s| s == "vkCmdToyDispatch").is_err());
    assert!(validusage::parse_where(&text[..cut_json(&text)], "v.json", &others).is_err());
    // an id that is no VUID has no scope to skip it by
    let bad = text.replacen("VUID-VkToyRegion-stride-00003", "NOT-A-VUID", 1);
    assert!(validusage::parse_where(&bad, "v.json", &|s| s == "vkCmdToyDispatch").is_err());
    // missing validation
    let e = validusage::parse("{\"version info\": {}}", "v.json").unwrap_err();
    assert!(e.to_string().contains("validation"), "{e}");
    // every cut point fails cleanly
    for cut in (0..text.len()).step_by(13) {
        let e = validusage::parse(&text[..cut], "v.json").unwrap_err();
        assert!(e.location().is_some(), "{e}");
    }
}

#[test]
fn load_vuids_accepts_dirs_json_and_man_pages() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        common::fixture("validusage_1_4.json"),
        dir.path().join("validusage.json"),
    )
    .unwrap();
    assert_eq!(load_vuids(dir.path()).unwrap().len(), 4);
    assert_eq!(
        load_vuids(&common::fixture("toy_plain.txt")).unwrap().len(),
        4
    );
    let empty = tempfile::tempdir().unwrap();
    let e = load_vuids(empty.path()).unwrap_err();
    assert!(
        matches!(e, RegistryError::NotFound { .. })
            && e.to_string().contains("validusage.json: file not found"),
        "{e}"
    );
    let e = load_vuids(&PathBuf::from("/nonexistent/page.md")).unwrap_err();
    assert_eq!(e.to_string(), "/nonexistent/page.md: file not found");
    // errors name the path
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{\"validation\": [").unwrap();
    let e = load_vuids(&bad).unwrap_err();
    assert!(
        e.to_string().starts_with(&format!("{}:1:", bad.display())),
        "{e}"
    );
}

#[test]
fn union_first_source_wins() {
    let paths = vec![
        common::fixture("validusage_1_4.json"),
        common::fixture("validusage_1_3.json"),
        common::fixture("toy_html.md"),
    ];
    let u = load_union(&paths).unwrap();
    assert_eq!(u.len(), 6);
    assert_eq!(u.version.as_deref(), Some("1.4.999"));
    assert!(
        u.get("VUID-vkCmdToyDispatch-stride-00001")
            .unwrap()
            .text
            .ends_with("limit"),
        "1.4 record kept"
    );
    assert_eq!(
        u.get("VUID-vkCmdToyDispatch-pRegion-00002")
            .unwrap()
            .condition
            .to_string(),
        "VK_KHR_toy_dispatch+!(VK_VERSION_1_3,VK_KHR_toy_extra)"
    );
    let ids = u.ids();
    let mut sorted = ids.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(ids, sorted);
}

#[test]
fn reports() {
    let a = old_schema();
    let b = new_schema();
    assert_eq!(
        report::vuids_plain(&a, Some("vkCmdToyDispatch")),
        "VUID-vkCmdToyDispatch-commandBuffer-parameter\nVUID-vkCmdToyDispatch-pRegion-00002\nVUID-vkCmdToyDispatch-renderpass\nVUID-vkCmdToyDispatch-stride-00001\n"
    );
    assert_eq!(report::vuids_plain(&a, None).lines().count(), 5);
    let j: serde_json::Value =
        serde_json::from_str(&report::vuids_json(&a, Some("VkToyRegion"))).unwrap();
    assert_eq!(
        j,
        serde_json::json!([{
            "id": "VUID-VkToyRegion-stride-00003",
            "scope": "VkToyRegion",
            "implicit": false,
            "condition": "core",
            "text": "`stride` must be less than `2`32"
        }])
    );
    let d = report::diff(&a, &b, Some("vkCmdToyDispatch"));
    let expected = format!(
        "--- {} (1.3.999)\n+++ {} (1.4.999)\nadded: 1, removed: 2, changed: 1\n\nadded:\n+ VUID-vkCmdToyDispatch-pRegion-00004\n\nremoved:\n- VUID-vkCmdToyDispatch-pRegion-00002\n- VUID-vkCmdToyDispatch-renderpass\n\nchanged:\n~ VUID-vkCmdToyDispatch-stride-00001\n    condition - VK_KHR_toy_dispatch\n    condition + core\n    text - `pRegion->stride` must be a multiple of the toy’s `toyAlign`\n    text + `pRegion->stride` must be a multiple of the toy’s `toyAlign` limit\n",
        a.origin, b.origin
    );
    assert_eq!(d, expected);
    assert!(report::diff(&a, &a, None).contains("added: 0, removed: 0, changed: 0"));
}

#[test]
fn diff_can_leave_out_condition_only_changes() {
    let a = old_schema();
    let b = new_schema();
    // `a` with one VUID's condition taken from `b`, its text unchanged.
    let mut c = a.clone();
    let id = "VUID-vkCmdToyDispatch-stride-00001";
    let k = c.records.iter().position(|r| r.id == id).unwrap();
    c.records[k].condition = b.get(id).unwrap().condition.clone();
    assert_ne!(c.records[k].condition, a.get(id).unwrap().condition);
    let all = report::diff(&a, &c, None);
    assert!(all.contains("added: 0, removed: 0, changed: 1\n"), "{all}");
    assert!(all.contains("    condition + core\n"), "{all}");
    let options = report::DiffOptions {
        command: None,
        ignore_conditions: true,
    };
    let text_only = report::diff_with(&a, &c, &options);
    assert!(
        text_only.contains(
            "added: 0, removed: 0, changed: 0 (1 changed in their condition only, left out)\n"
        ),
        "{text_only}"
    );
    assert!(!text_only.contains(id), "{text_only}");
    // A change of text is still listed, without its condition lines.
    let both = report::diff_with(&a, &b, &options);
    assert!(both.contains(&format!("~ {id}\n    text - ")), "{both}");
    assert!(!both.contains("condition -"), "{both}");
}

/// A text or a condition that is no string is reported at its JSON path where its scope is kept,
/// and not read where it is not.
#[test]
fn a_text_that_is_no_string_is_reported_only_where_its_scope_is_kept() {
    let text = common::fixture_text("validusage_1_3.json");
    let region = |s: &str| s == "VkToyRegion";
    let others = |s: &str| s != "VkToyRegion";
    let stride = "\"text\": \"<code>stride</code>";
    assert!(text.contains(stride));
    for (bad, path, found) in [
        (
            text.replacen(stride, "\"text\": 7, \"x\": \"", 1),
            "$.validation.VkToyRegion.core[0].text",
            "found a number",
        ),
        (
            text.replacen(stride, "\"text\": {\"a\": \"\"}, \"x\": \"", 1),
            "$.validation.VkToyRegion.core[0].text",
            "found an object",
        ),
        (
            text.replacen(stride, "\"condition\": [\"VK_A\"], \"text\": \"", 1),
            "$.validation.VkToyRegion.core[0].condition",
            "found an array",
        ),
    ] {
        for e in [
            validusage::parse_where(&bad, "v.json", &region).unwrap_err(),
            validusage::parse(&bad, "v.json").unwrap_err(),
        ] {
            match e.location() {
                Some(Location::JsonPathAt { path: p, .. }) => assert_eq!(p, path, "{e}"),
                other => panic!("expected a JSON path, got {other:?}: {e}"),
            }
            assert!(e.to_string().contains(found), "{e}");
        }
        let set = validusage::parse_where(&bad, "v.json", &others).expect("the other scopes read");
        assert_eq!(
            set,
            validusage::parse_where(&text, "v.json", &others).unwrap()
        );
    }
}
