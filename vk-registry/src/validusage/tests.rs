//! The reading against the reference (the reading as it was) on the fixtures, on many mutations
//! of them and on the installed registry; the scan against serde_json.

use super::*;
use crate::error::Location;

const ORIGIN: &str = "v.json";

fn fixture(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A compact document with per-entry conditions, an escape and an empty array.
const COMPACT: &str = r#"{"version info":{"schema version":2,"api version":"1.3.1"},
 "validation":{
  "vkCmdToyCopy":{
   "!(VK_KHR_a)+(VK_KHR_b|VK_VERSION_1_2),VK_EXT_c&VK_EXT_d":[
    {"vuid":"VUID-vkCmdToyCopy-dst-00030","text":"<code>dst</code> &amp; <em>src</em> <strong class=\"purple\">must</strong> differ","condition":"VK_KHR_e"},
    {"vuid":"VUID-vkCmdToyCopy-src-00031","condition":null,"text":"a\/b\\c\td\ne\rf\bg\fh"}],
   "core":[]},
  "VkToyRegion":{"core":[{"vuid":"VUID-VkToyRegion-stride-00031","text":"stride must be &lt; 2<sup>32</sup>","page":7}]}}}"#;

fn documents() -> Vec<(&'static str, String)> {
    vec![
        ("validusage_1_3.json", fixture("validusage_1_3.json")),
        ("validusage_1_4.json", fixture("validusage_1_4.json")),
        ("compact", COMPACT.to_string()),
    ]
}

fn all(_: &str) -> bool {
    true
}
fn none(_: &str) -> bool {
    false
}
fn dispatch(s: &str) -> bool {
    s == "vkCmdToyDispatch"
}
fn region(s: &str) -> bool {
    s == "VkToyRegion"
}
fn copy(s: &str) -> bool {
    s == "vkCmdToyCopy"
}
fn not_dispatch(s: &str) -> bool {
    s != "vkCmdToyDispatch"
}

/// A filter of scopes, named.
type Filter = (&'static str, fn(&str) -> bool);

const FILTERS: [Filter; 6] = [
    ("all", all),
    ("none", none),
    ("dispatch", dispatch),
    ("region", region),
    ("copy", copy),
    ("not dispatch", not_dispatch),
];

/// A reading's outcome in full: the set, or the error with its location.
fn outcome(r: &Result<VuidSet, RegistryError>) -> String {
    match r {
        Ok(set) => format!("{set:?}"),
        Err(e) => format!("{e} ({:?})", e.location()),
    }
}

/// Whether the reference's error for `doc` is a problem of shape in the text or the condition of
/// an entry that `keep` skips (which the reading does not read): where serde_json stopped, in the
/// document as the reading's serde_json types read it.
fn is_about_a_skipped_entry(
    doc: &str,
    old: &Result<VuidSet, RegistryError>,
    keep: fn(&str) -> bool,
) -> bool {
    let Some(Location::JsonPathAt { line, column, .. }) =
        old.as_ref().err().and_then(|e| e.location())
    else {
        return false;
    };
    let Ok(d) = serde_json::from_str::<Doc>(doc) else {
        return false;
    };
    let line_start: usize = doc.split_inclusive('\n').take(line - 1).map(str::len).sum();
    let at = line_start + column;
    d.validation
        .values()
        .flat_map(|conds| conds.values())
        .flatten()
        .filter(|e| !is_kept(&e.vuid, &keep))
        .flat_map(|e| std::iter::once(e.text).chain(e.condition))
        .any(|raw| {
            let start = offset_in(doc, raw.get());
            (start..=start + raw.get().len()).contains(&at)
        })
}

/// Reads `doc` with `keep` every way and checks that the readings agree with each other and with
/// the reference; whether the scan read it.
fn check(doc: &str, what: &str, keep: Filter) -> bool {
    let (name, keep) = keep;
    let new = parse_where(doc, ORIGIN, &keep);
    let old = reference::parse_where(doc, ORIGIN, &keep);
    let scanned = scan::scan(doc, &mut ScopeFilter::new(&keep)).is_some();
    if scanned {
        // The scan reads only documents without a JSON error, as serde_json reads them.
        assert!(
            serde_json::from_str::<StrictDoc>(doc).is_ok(),
            "{what}, {name}: the scan read a document with a JSON error:\n{doc}"
        );
        let by_serde = parse_where_by_serde(doc, ORIGIN, &keep);
        assert_eq!(
            outcome(&new),
            outcome(&by_serde),
            "{what}, {name}: the scan and serde_json read\n{doc}"
        );
    }
    // An error of the reference about an entry `keep` skips is not the reading's to report
    // (unless the document has another problem of its JSON or shape, which it then reports as
    // the reference does).
    if !is_about_a_skipped_entry(doc, &old, keep) {
        assert_eq!(
            outcome(&new),
            outcome(&old),
            "{what}, {name}: the reading and the reference differ on\n{doc}"
        );
    }
    scanned
}

/// A small deterministic generator (xorshift*).
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33) as usize % n
    }
    fn pick<'a>(&mut self, items: &[&'a str]) -> &'a str {
        items[self.below(items.len())]
    }
}

/// JSON values and fragments that the mutations put in documents.
const VALUES: [&str; 24] = [
    "7",
    "-0",
    "01",
    "1.5e3",
    "null",
    "true",
    "[1]",
    "{\"a\":1}",
    "[\"\\ud800\"]",
    "\"\\ud800\"",
    "\"\\udc00x\"",
    "\"a\\u00e9b\"",
    "\"\\ud83d\\ude00\"",
    "\"x\\\\y \\\" \\/ \\t\"",
    "\"bad \\q escape\"",
    "\"tab\there\"",
    "\"VK_KHR_x+\"",
    "\"core\"",
    "\"\"",
    "\"VUID-VkToyRegion-stride-00003\"",
    "\"VUID-vkCmdToyCopy-x-1\"",
    "\"NOT-A-VUID\"",
    "\"VUID-vkCmdToy\\u0044ispatch-x-9\"",
    "\"VUID-VkToyRegion-bad field-1\"",
];

const FRAGMENTS: [&str; 22] = [
    "\"",
    "\\",
    "{",
    "}",
    "[",
    "]",
    ",",
    ":",
    " ",
    "\n",
    "\t",
    "\u{1}",
    "\\u00e9",
    "\\ud800",
    "\\q",
    "null",
    "7",
    "é",
    "\"x\":1,",
    "\"condition\":\"VK_X\",",
    "\"condition\":7,",
    "\"text\":\"again\",",
];

/// The byte ranges of the values of the members named `key`, strings only.
fn string_values(doc: &str, key: &str) -> Vec<(usize, usize)> {
    let b = doc.as_bytes();
    let pat = format!("\"{key}\"");
    let mut out = Vec::new();
    for (at, _) in doc.match_indices(&pat) {
        let mut i = at + pat.len();
        while b.get(i).is_some_and(|c| c.is_ascii_whitespace()) {
            i += 1;
        }
        if b.get(i) != Some(&b':') {
            continue;
        }
        i += 1;
        while b.get(i).is_some_and(|c| c.is_ascii_whitespace()) {
            i += 1;
        }
        if b.get(i) != Some(&b'"') {
            continue;
        }
        let start = i;
        i += 1;
        while i < b.len() && b[i] != b'"' {
            i += if b[i] == b'\\' { 2 } else { 1 };
        }
        if i < b.len() {
            out.push((start, i + 1));
        }
    }
    out
}

/// `doc` with one random change.
fn mutate(doc: &str, rng: &mut Rng) -> String {
    let boundary = |rng: &mut Rng| loop {
        let at = rng.below(doc.len() + 1);
        if doc.is_char_boundary(at) {
            break at;
        }
    };
    match rng.below(7) {
        0 => {
            let at = boundary(rng);
            let end = (at + 1..=doc.len())
                .find(|&e| doc.is_char_boundary(e))
                .unwrap_or(at);
            format!("{}{}", &doc[..at], &doc[end..])
        }
        1 => {
            let at = boundary(rng);
            format!("{}{}{}", &doc[..at], rng.pick(&FRAGMENTS), &doc[at..])
        }
        2 | 3 => {
            let key = rng.pick(&["text", "text", "vuid", "condition", "api version", "page"]);
            let values = string_values(doc, key);
            if values.is_empty() {
                return doc.to_string();
            }
            let (start, end) = values[rng.below(values.len())];
            format!("{}{}{}", &doc[..start], rng.pick(&VALUES), &doc[end..])
        }
        4 => {
            // a member put in an entry
            let opens: Vec<usize> = doc.match_indices("\"vuid\"").map(|(at, _)| at).collect();
            if opens.is_empty() {
                return doc.to_string();
            }
            let at = opens[rng.below(opens.len())];
            let name = rng.pick(&["condition", "condition", "text", "vuid", "page"]);
            format!(
                "{}\"{name}\": {}, {}",
                &doc[..at],
                rng.pick(&VALUES),
                &doc[at..]
            )
        }
        5 => {
            // a key changed
            let keys: Vec<(usize, usize)> = doc
                .match_indices("\":")
                .filter_map(|(end, _)| Some((doc[..end].rfind('"')?, end + 1)))
                .collect();
            if keys.is_empty() {
                return doc.to_string();
            }
            let (start, end) = keys[rng.below(keys.len())];
            let key = rng.pick(&[
                "\"(VK_A\"",
                "\"c\\u006fre\"",
                "\"core\"",
                "\"VK_B+!VK_C\"",
                "\"vkCmdToyDispatch\"",
                "\"VkToyRegion\"",
                "\"vuid\"",
                "\"text\"",
                "\"validation\"",
                "\"version info\"",
                "\"x\\ty\"",
            ]);
            format!("{}{key}{}", &doc[..start], &doc[end..])
        }
        _ => {
            // a line given twice
            let lines: Vec<&str> = doc.split_inclusive('\n').collect();
            let k = rng.below(lines.len());
            let mut out = String::new();
            for (i, l) in lines.iter().enumerate() {
                out.push_str(l);
                if i == k {
                    out.push_str(l);
                }
            }
            out
        }
    }
}

#[test]
fn the_fixtures_read_as_the_reference_reads_them_the_scan_reading_them() {
    for (name, doc) in documents() {
        for keep in FILTERS {
            assert!(check(&doc, name, keep), "{name}: the scan reads it");
        }
    }
}

#[test]
fn mutated_documents_read_as_the_reference_reads_them() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut scanned, mut total) = (0, 0);
    for (name, doc) in documents() {
        for round in 0..700 {
            let mut m = mutate(&doc, &mut rng);
            if round % 4 == 3 {
                m = mutate(&m, &mut rng);
            }
            for keep in FILTERS {
                total += 1;
                if check(&m, &format!("{name} mutation {round}"), keep) {
                    scanned += 1;
                }
            }
        }
    }
    // both readings are exercised
    assert!(
        scanned > total / 5 && scanned < total * 4 / 5,
        "{scanned} of {total} scanned"
    );
}

#[test]
fn every_prefix_fails_as_for_the_reference() {
    for (name, doc) in documents() {
        for cut in 0..doc.len() {
            if doc.is_char_boundary(cut) {
                for keep in [FILTERS[0], FILTERS[2]] {
                    check(&doc[..cut], &format!("{name} cut at {cut}"), keep);
                }
            }
        }
    }
}

#[test]
fn a_text_or_condition_that_is_no_string_is_reported_only_where_its_scope_is_kept() {
    let doc = fixture("validusage_1_3.json");
    let text = "\"text\": \"<code>stride</code>";
    assert!(doc.contains(text));
    for (bad, path) in [
        (
            doc.replacen(text, "\"text\": 7, \"x\": \"", 1),
            "$.validation.VkToyRegion.core[0].text",
        ),
        (
            doc.replacen(text, "\"condition\": [1], \"text\": \"", 1),
            "$.validation.VkToyRegion.core[0].condition",
        ),
        (
            doc.replacen(text, "\"text\": \"\\ud800<code>stride</code>", 1),
            "",
        ),
    ] {
        let e = parse_where(&bad, ORIGIN, &region).unwrap_err();
        let old = reference::parse_where(&bad, ORIGIN, &region).unwrap_err();
        assert_eq!(outcome(&Err(e)), outcome(&Err(old)));
        let e = parse_where(&bad, ORIGIN, &region).unwrap_err();
        if path.is_empty() {
            // a lone surrogate is a JSON error wherever it is
            assert!(
                matches!(e.location(), Some(Location::LineCol { .. })),
                "{e}"
            );
            assert!(parse_where(&bad, ORIGIN, &dispatch).is_err());
        } else {
            assert!(
                matches!(e.location(), Some(Location::JsonPathAt { path: p, .. }) if p == path),
                "{e}"
            );
            let skipped = parse_where(&bad, ORIGIN, &dispatch).expect("not read");
            let want = reference::parse_where(&doc, ORIGIN, &dispatch).unwrap();
            assert_eq!(skipped, want);
        }
    }
}

#[test]
fn the_scan_leaves_what_it_does_not_read_to_serde_json() {
    let doc = fixture("validusage_1_3.json");
    let scans = |d: &str| scan::scan(d, &mut ScopeFilter::new(&all)).is_some();
    assert!(scans(&doc));
    for (from, to) in [
        ("must", "\\u006dust"),
        ("\"core\"", "\"c\\u006fre\""),
        ("VUID-VkToyRegion", "VUID-\\u0056kToyRegion"),
        ("1.3.999", "1.3.\\u0039"),
        ("\"schema version\": 2", "\"schema version\": 2.5"),
        ("\"schema version\": 2", "\"schema version\": [2]"),
        ("\"schema version\": 2", "\"schema version\": 02"),
        ("\"version info\": {", "\"version info\": null, \"v\": {"),
        ("\"VkToyRegion\": {", "\"vkCmdToyDispatch\": {"),
        ("\"(VK_KHR_toy_dispatch)\"", "\"core\""),
        ("}\n  }\n}", "}\n  },\n  \"validation\": {}\n}"),
        ("\"text\": \"This", "\"text\": \"x\", \"text\": \"This"),
        (
            "\"text\": \"This",
            "\"vuid\": \"VUID-a-b\", \"text\": \"This",
        ),
        ("\"comment\"", "\"api version\": \"1\", \"comment\""),
        ("\"comment\"", "\"version info\": {}, \"comment\""),
        ("}\n  }\n}", "}\n  }\n}\n!"),
        ("{", "\u{feff}{"),
        ("[\n        {", "[\n        {}, {"),
        ("\"text\": \"This", "\"p\": [], \"text\": \"This"),
    ] {
        assert!(doc.contains(from), "{from}");
        let changed = doc.replacen(from, to, 1);
        assert!(!scans(&changed), "{from} -> {to}");
        for keep in FILTERS {
            check(&changed, &format!("{from} -> {to}"), keep);
        }
    }
    // Whitespace, escapes of one character, `null` conditions and other members are read.
    for (from, to) in [
        ("\n", "\r\n\t "),
        ("must", "mu\\\"s\\\\t\\/"),
        ("\"text\": \"This", "\"condition\": null, \"text\": \"This"),
        (
            "\"comment\"",
            "\"n\": -12, \"t\": true, \"f\": false, \"z\": null, \"comment\"",
        ),
    ] {
        let changed = doc.replace(from, to);
        assert!(scans(&changed), "{from} -> {to}");
        for keep in FILTERS {
            check(&changed, &format!("{from} -> {to}"), keep);
        }
    }
}

#[test]
fn the_scope_filter_agrees_with_split_vuid() {
    let mut rng = Rng(7);
    let parts = [
        "VUID-", "VUID", "vkCmdA", "vkCmdA2", "VkB", "-", "--", "x", "01234", ":", "_", " ", "é",
        "vkCmdA-", "a", "",
    ];
    let keeps: [fn(&str) -> bool; 4] = [all, none, |s| s == "vkCmdA", |s| s.len() > 3];
    for keep in keeps {
        let mut filter = ScopeFilter::new(&keep);
        let mut ids = Vec::new();
        while ids.len() < 20_000 {
            // runs of ids, most of one scope
            let scope: String = (0..rng.below(3)).map(|_| rng.pick(&parts)).collect();
            for _ in 0..rng.below(5) {
                let prefix = if rng.below(4) == 0 { "" } else { "VUID-" };
                let dash = if rng.below(4) == 0 { "" } else { "-" };
                let tail: String = (0..rng.below(4)).map(|_| rng.pick(&parts)).collect();
                ids.push(format!("{prefix}{scope}{dash}{tail}"));
            }
        }
        for id in &ids {
            assert_eq!(filter.keeps(id), is_kept(id, &keep), "{id:?}");
        }
    }
}

#[test]
fn unescaping_agrees_with_serde_json() {
    for s in [
        "\"\"",
        "\"plain\"",
        "\"\\\"\"",
        "\"a\\\\b\\/c\\bd\\fe\\nf\\rg\\th\\\"\"",
        "\"é \\\\\\\\ ü\\n\"",
        "\"\\\\\"",
    ] {
        assert_eq!(scan::unescape(s), raw_str(s).unwrap(), "{s}");
    }
}

/// The installed registry's validusage.json.
fn installed() -> String {
    let path = Path::new(crate::DEFAULT_REGISTRY_DIR).join("validusage.json");
    read_to_string(&path).expect("the installed registry (libvulkan-dev) has validusage.json")
}

fn ray_tracing(s: &str) -> bool {
    matches!(
        s,
        "vkCmdTraceRaysIndirectKHR"
            | "vkCmdTraceRaysKHR"
            | "vkCmdTraceRaysNV"
            | "vkCmdBuildAccelerationStructuresIndirectKHR"
    )
}

fn structures(s: &str) -> bool {
    s.starts_with("Vk")
}

#[test]
fn the_installed_registry_reads_as_the_reference_reads_it() {
    // and the 1.4.309 one, where tests/common.rs has fetched it
    let fetched = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../target/registry/1.4.309/usr/share/vulkan/registry/validusage.json");
    let docs = std::iter::once(installed()).chain(read_to_string(&fetched).ok());
    for doc in docs {
        assert!(scan::scan(&doc, &mut ScopeFilter::new(&all)).is_some());
        for keep in [all as fn(&str) -> bool, ray_tracing, structures] {
            let new = parse_where(&doc, ORIGIN, &keep).unwrap();
            assert_eq!(new, reference::parse_where(&doc, ORIGIN, &keep).unwrap());
            assert_eq!(new, parse_where_by_serde(&doc, ORIGIN, &keep).unwrap());
        }
        let rt = parse_where(&doc, ORIGIN, &ray_tracing).unwrap();
        assert!(rt.len() > 100, "{}", rt.len());
    }
}

#[test]
fn in_the_installed_registry_a_text_that_is_no_string_is_reported_where_its_scope_is_kept() {
    let doc = installed();
    let at = doc.find("\"VUID-vkCmdTraceRaysNV-").unwrap();
    let text = at + doc[at..].find("\"text\": \"").unwrap() + "\"text\": ".len();
    let bad = format!("{}{{\"a\": 1}}, \"b\": {}", &doc[..text], &doc[text..]);
    let e = parse_where(&bad, ORIGIN, &ray_tracing).unwrap_err();
    let old = reference::parse_where(&bad, ORIGIN, &ray_tracing).unwrap_err();
    assert_eq!(outcome(&Err(e)), outcome(&Err(old)));
    let e = parse_where(&bad, ORIGIN, &ray_tracing).unwrap_err();
    assert!(
        matches!(e.location(), Some(Location::JsonPathAt { path, .. }) if path.starts_with("$.validation.vkCmdTraceRaysNV.") && path.ends_with("].text")),
        "{e}"
    );
    let skipped = parse_where(&bad, ORIGIN, &structures).unwrap();
    assert_eq!(
        skipped,
        reference::parse_where(&doc, ORIGIN, &structures).unwrap()
    );
}
