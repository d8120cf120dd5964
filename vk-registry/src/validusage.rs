//! validusage.json (schema 2 as in 1.3.x with condition-expression keys, and the 1.4.x
//! form where everything is under `core`) into a [`VuidSet`].
//!
//! A reading builds nothing for the entries whose scope it skips (see [`parse_where`]). The
//! document in its usual form is read by a scan (`scan.rs`) that checks the JSON in one pass and
//! keeps the raw JSON of the kept entries' texts and conditions, unescaped only then. Any other
//! document (an escape in a key or an id, a `\u` escape, a key given twice, a JSON error...) is
//! deserialised with serde_json into borrowed structures that keep each entry's `text` and
//! `condition` as raw JSON, checked to be strings only where the entry is kept. Where the document
//! does not read that way (its syntax, or its shape elsewhere) it is read again with every text
//! and condition a string, which names the first problem of the document as a whole; a problem of
//! shape is located by re-reading the input as a generic value to name its JSON path.

use crate::error::{excerpt, line_col, read_to_string, Location, RegistryError};
use crate::vuid::{is_vuid_part, normalize_html, split_vuid, Condition, VuidRecord, VuidSet};
use serde::Deserialize;
use serde_json::value::RawValue;
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

#[cfg(test)]
mod reference;
mod scan;
#[cfg(test)]
mod tests;

/// The document, each entry's text and condition left raw.
#[derive(Deserialize)]
struct Doc<'a> {
    #[serde(rename = "version info", default, borrow)]
    version_info: Option<VersionInfo<'a>>,
    #[serde(borrow)]
    validation: HashMap<Key<'a>, HashMap<Key<'a>, Vec<Entry<'a>>>>,
}

#[derive(Deserialize)]
struct VersionInfo<'a> {
    #[serde(rename = "api version", default, borrow)]
    api_version: Option<Cow<'a, str>>,
}

#[derive(Deserialize, PartialEq, Eq, Hash)]
struct Key<'a>(#[serde(borrow)] Cow<'a, str>);

#[derive(Deserialize)]
struct Entry<'a> {
    #[serde(borrow)]
    vuid: Cow<'a, str>,
    /// A string; raw JSON, unescaped (and checked to be a string) only where the entry is kept.
    #[serde(borrow)]
    text: &'a RawValue,
    /// A per-entry condition, should a schema carry one; raw like `text`.
    #[serde(default, borrow)]
    condition: Option<&'a RawValue>,
}

/// The document with every text and condition a string: read only for the error where the
/// document has one, which is then its first problem in the order of the text.
#[derive(Deserialize)]
#[cfg_attr(not(test), allow(dead_code))]
struct StrictDoc<'a> {
    #[serde(rename = "version info", default, borrow)]
    version_info: Option<VersionInfo<'a>>,
    #[serde(borrow)]
    validation: HashMap<Key<'a>, HashMap<Key<'a>, Vec<StrictEntry<'a>>>>,
}

#[derive(Deserialize)]
#[cfg_attr(not(test), allow(dead_code))]
struct StrictEntry<'a> {
    #[serde(borrow)]
    vuid: Cow<'a, str>,
    #[serde(borrow)]
    text: Cow<'a, str>,
    #[serde(default, borrow)]
    condition: Option<Cow<'a, str>>,
}

/// A JSON string, borrowed where it holds no escape.
#[derive(Deserialize)]
struct Str<'a>(#[serde(borrow)] Cow<'a, str>);

/// The string the raw JSON `raw` holds, unescaped.
fn raw_str(raw: &str) -> Result<Cow<'_, str>, serde_json::Error> {
    serde_json::from_str::<Str>(raw).map(|s| s.0)
}

/// [`raw_str`] for a string the scan has read: its escapes are all one character.
fn scanned_str(raw: &str) -> Result<Cow<'_, str>, serde_json::Error> {
    Ok(scan::unescape(raw))
}

/// Read a validusage.json file.
pub fn load(path: &Path) -> Result<VuidSet, RegistryError> {
    load_where(path, &|_| true)
}

/// Read a validusage.json file, keeping the VUIDs whose scope `keep` accepts (see [`parse_where`]).
pub fn load_where(path: &Path, keep: &dyn Fn(&str) -> bool) -> Result<VuidSet, RegistryError> {
    let text = read_to_string(path)?;
    parse_where(&text, &path.display().to_string(), keep)
}

/// Parse validusage.json text; `origin` names the source in errors and in the set.
pub fn parse(text: &str, origin: &str) -> Result<VuidSet, RegistryError> {
    parse_where(text, origin, &|_| true)
}

/// Whether an entry with this id is read: where its scope is kept, and where the id is no VUID
/// (to be reported).
fn is_kept(id: &str, keep: &dyn Fn(&str) -> bool) -> bool {
    split_vuid(id).is_none_or(|p| keep(p.scope))
}

/// [`is_kept`] for the ids of a document in turn: the scope of one id is most often the one of
/// the id before, and `keep` is asked once for a run of ids of one scope.
struct ScopeFilter<'k, 'a> {
    keep: &'k dyn Fn(&str) -> bool,
    /// The scope of the id before, whether it is a VUID part, and whether it is kept.
    last: Option<(&'a str, bool, bool)>,
}

impl<'k, 'a> ScopeFilter<'k, 'a> {
    fn new(keep: &'k dyn Fn(&str) -> bool) -> Self {
        ScopeFilter { keep, last: None }
    }

    /// [`is_kept`]`(id, keep)`.
    fn keeps(&mut self, id: &'a str) -> bool {
        // `split_vuid`: `VUID-`, a scope up to the first `-`, and the rest, both VUID parts.
        let Some(rest) = id.strip_prefix("VUID-") else {
            return true;
        };
        // The scope of the id before holds no `-`: where `rest` starts with it and a `-`, it is
        // the scope of this id too.
        let (tail, valid, kept) = match self.last {
            Some((s, valid, kept))
                if rest.as_bytes().get(s.len()) == Some(&b'-') && rest.starts_with(s) =>
            {
                (&rest[s.len() + 1..], valid, kept)
            }
            _ => {
                let Some(dash) = rest.bytes().position(|b| b == b'-') else {
                    return true;
                };
                let scope = &rest[..dash];
                let valid = is_vuid_part(scope);
                let kept = valid && (self.keep)(scope);
                self.last = Some((scope, valid, kept));
                (&rest[dash + 1..], valid, kept)
            }
        };
        kept || !valid || !is_vuid_part(tail)
    }
}

/// [`parse`], keeping only the VUIDs whose scope (the command or structure their id names)
/// `keep` accepts. The others' text and condition are never unescaped nor normalised, nor their
/// condition key read, so an error in them is not reported, a text or condition that is no string
/// included. The document's JSON is still checked whole: a syntax error anywhere (a `\u` escape
/// that is no character in a skipped text included), or a problem of shape outside the skipped
/// texts and conditions, is reported as the first problem of the document. An id that is no VUID
/// has no scope to skip it by: it is reported. A run judges with a few scopes of the registry's
/// thousands.
pub fn parse_where(
    text: &str,
    origin: &str,
    keep: &dyn Fn(&str) -> bool,
) -> Result<VuidSet, RegistryError> {
    let mut filter = ScopeFilter::new(keep);
    match scan::scan(text, &mut filter) {
        // The document holds no JSON error: the errors are those of the kept entries.
        Some(doc) => read_groups(
            text,
            origin,
            doc.version,
            doc.groups,
            keep,
            &|e| e,
            scanned_str,
        ),
        None => parse_where_by_serde(text, origin, keep),
    }
}

/// [`parse_where`] with serde_json, for any document (the scan reads only the usual form).
fn parse_where_by_serde(
    text: &str,
    origin: &str,
    keep: &dyn Fn(&str) -> bool,
) -> Result<VuidSet, RegistryError> {
    let doc: Doc = match serde_json::from_str(text) {
        Ok(d) => d,
        Err(e) => {
            return Err(
                strict_error(text, origin).unwrap_or_else(|| locate_json_error(text, origin, e))
            )
        }
    };
    // A `\u` escape may be no character (a lone surrogate), which the raw values let pass.
    if text.contains("\\u") {
        if let Some(e) = raw_problem(text, origin, &doc, keep) {
            return Err(e);
        }
    }
    let version = doc
        .version_info
        .as_ref()
        .and_then(|v| v.api_version.as_deref());
    let mut filter = ScopeFilter::new(keep);
    let mut groups = Vec::new();
    for (scope, conds) in &doc.validation {
        for (key, entries) in conds {
            let mut kept = Vec::new();
            for (index, e) in entries.iter().enumerate() {
                if filter.keeps(&e.vuid) {
                    kept.push(Kept {
                        index,
                        vuid: &e.vuid,
                        text: e.text.get(),
                        condition: e.condition.map(RawValue::get),
                    });
                }
            }
            if !kept.is_empty() {
                groups.push(Group {
                    scope: &scope.0,
                    key: &key.0,
                    kept,
                });
            }
        }
    }
    // Every problem of the document's raw values that the reading reports comes first, as the
    // first problem of the document when they are read as strings.
    let fail = |e: RegistryError| raw_problem(text, origin, &doc, keep).unwrap_or(e);
    read_groups(text, origin, version, groups, keep, &fail, raw_str)
}

/// An entry a reading keeps: its index in its array, its id, and the raw JSON of its text and
/// condition (slices of the document).
struct Kept<'a> {
    index: usize,
    vuid: &'a str,
    text: &'a str,
    condition: Option<&'a str>,
}

/// The kept entries of a scope's condition key.
struct Group<'a> {
    scope: &'a str,
    key: &'a str,
    kept: Vec<Kept<'a>>,
}

/// The set of the kept entries of `text`, read by scope and condition key in order (so that
/// errors and duplicate resolution are deterministic); `string` reads a raw text or condition,
/// and `fail` turns the error of an entry into the one to report.
fn read_groups(
    text: &str,
    origin: &str,
    version: Option<&str>,
    mut groups: Vec<Group>,
    keep: &dyn Fn(&str) -> bool,
    fail: &dyn Fn(RegistryError) -> RegistryError,
    string: fn(&str) -> Result<Cow<'_, str>, serde_json::Error>,
) -> Result<VuidSet, RegistryError> {
    groups.sort_unstable_by(|a, b| (a.scope, a.key).cmp(&(b.scope, b.key)));
    let mut cond_cache: HashMap<&str, Condition> = HashMap::new();
    let mut records = Vec::with_capacity(groups.iter().map(|g| g.kept.len()).sum());
    for Group { scope, key, kept } in groups {
        let cond = match cond_cache.get(key) {
            Some(c) => c.clone(),
            None => {
                let c = Condition::parse(key).map_err(|(off, msg)| {
                    fail(json_path_error(
                        text,
                        origin,
                        &format!("$.validation.{scope}"),
                        &format!(
                            "bad condition key `{}` at offset {off}: {msg}",
                            excerpt(key)
                        ),
                    ))
                })?;
                cond_cache.insert(key, c.clone());
                c
            }
        };
        for e in kept {
            let i = e.index;
            let cond = match e.condition {
                Some(raw) => {
                    let c =
                        string(raw).map_err(|err| fail(raw_error(text, origin, raw, err, keep)))?;
                    Condition::parse(&c).map_err(|(off, msg)| {
                        fail(json_path_error(
                            text,
                            origin,
                            &format!("$.validation.{scope}.{key}[{i}].condition"),
                            &format!("bad condition at offset {off}: {msg}"),
                        ))
                    })?
                }
                None => cond.clone(),
            };
            let body =
                string(e.text).map_err(|err| fail(raw_error(text, origin, e.text, err, keep)))?;
            let rec = VuidRecord::new(e.vuid, cond, normalize_html(&body)).ok_or_else(|| {
                fail(json_path_error(
                    text,
                    origin,
                    &format!("$.validation.{scope}.{key}[{i}].vuid"),
                    &format!("`{}` is not a VUID", excerpt(e.vuid)),
                ))
            })?;
            records.push(rec);
        }
    }
    Ok(VuidSet::new(origin, version.map(str::to_string), records))
}

/// The error of the document read strictly ([`StrictDoc`]), if it has one.
fn strict_error(text: &str, origin: &str) -> Option<RegistryError> {
    serde_json::from_str::<StrictDoc>(text)
        .err()
        .map(|e| locate_json_error(text, origin, e))
}

/// The first problem, in the order of the text, of the raw values the reading reports: a kept
/// entry's text or condition that is no string, or any raw value that is no JSON a strict reading
/// accepts (a `\u` escape that is no character); `None` where there is none.
fn raw_problem(
    text: &str,
    origin: &str,
    doc: &Doc,
    keep: &dyn Fn(&str) -> bool,
) -> Option<RegistryError> {
    let mut first: Option<(usize, &str, serde_json::Error)> = None;
    for conds in doc.validation.values() {
        for entries in conds.values() {
            for e in entries {
                let kept = is_kept(&e.vuid, keep);
                for raw in std::iter::once(e.text)
                    .chain(e.condition)
                    .map(RawValue::get)
                {
                    if kept {
                        if let Err(err) = raw_str(raw) {
                            let at = offset_in(text, raw);
                            if first.as_ref().is_none_or(|f| at < f.0) {
                                first = Some((at, raw, err));
                            }
                        }
                    } else if raw.contains("\\u")
                        && serde_json::from_str::<serde_json::Value>(raw).is_err()
                    {
                        // A JSON error in a skipped entry: the document's first problem.
                        if let Some(e) = strict_error(text, origin) {
                            return Some(e);
                        }
                    }
                }
            }
        }
    }
    first.map(|(_, raw, err)| raw_error(text, origin, raw, err, keep))
}

/// The byte offset of a raw value of `text` in it.
fn offset_in(text: &str, raw: &str) -> usize {
    (raw.as_ptr() as usize)
        .checked_sub(text.as_ptr() as usize)
        .filter(|&at| at <= text.len())
        .unwrap_or(0)
}

/// The line and column of the byte `index` of `text` as serde_json counts them: the column is the
/// byte offset from the start of the line.
fn serde_position(text: &str, index: usize) -> (usize, usize) {
    let before = &text.as_bytes()[..index.min(text.len())];
    let start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |p| p + 1);
    let line = 1 + before[..start].iter().filter(|&&b| b == b'\n').count();
    (line, before.len() - start)
}

/// The error for `err`, met reading the raw value `raw` of `text` alone: located as where the
/// whole document is read strictly.
fn raw_error(
    text: &str,
    origin: &str,
    raw: &str,
    err: serde_json::Error,
    keep: &dyn Fn(&str) -> bool,
) -> RegistryError {
    let at = offset_in(text, raw);
    let (line, column) = if err.line() == 0 {
        serde_position(text, at)
    } else {
        // the byte of `raw` at serde_json's line and column
        let r = raw.as_bytes();
        let line_start = if err.line() == 1 {
            0
        } else {
            r.iter()
                .enumerate()
                .filter(|(_, &b)| b == b'\n')
                .nth(err.line() - 2)
                .map_or(r.len(), |(k, _)| k + 1)
        };
        serde_position(text, at + line_start + err.column())
    };
    let is_data = err.classify() == serde_json::error::Category::Data;
    located(
        text,
        origin,
        is_data,
        line,
        column,
        &message_of(&err),
        &|id| is_kept(id, keep),
    )
}

fn json_path_error(text: &str, origin: &str, path: &str, message: &str) -> RegistryError {
    // Try to find where the scope key appears, for a line:column as well.
    let _ = text;
    RegistryError::Parse {
        origin: origin.to_string(),
        location: Location::JsonPath(path.to_string()),
        message: message.to_string(),
    }
}

/// serde_json's message for `e`, without the position it adds.
fn message_of(e: &serde_json::Error) -> String {
    let s = e.to_string();
    if e.line() == 0 {
        return s;
    }
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    match s.strip_suffix(&suffix) {
        Some(m) => m.to_string(),
        None => s,
    }
}

fn locate_json_error(text: &str, origin: &str, e: serde_json::Error) -> RegistryError {
    let is_data = e.classify() == serde_json::error::Category::Data;
    located(
        text,
        origin,
        is_data,
        e.line(),
        e.column(),
        &message_of(&e),
        &|_| true,
    )
}

/// The error for a JSON problem that serde_json describes with `message` at `line`:`column` (as it
/// counts them; `line` 0 where it names none): a problem of shape (`is_data`) at the JSON path
/// of the first place where the document does not have its shape, the entries `kept` accepts the
/// ids of checked whole; any other at its line and column.
fn located(
    text: &str,
    origin: &str,
    is_data: bool,
    line: usize,
    column: usize,
    message: &str,
    kept: &dyn Fn(&str) -> bool,
) -> RegistryError {
    if is_data {
        // The syntax is fine; find the offending JSON path by walking a generic value.
        let path = serde_json::from_str::<serde_json::Value>(text)
            .ok()
            .and_then(|v| find_shape_error(&v, kept))
            .unwrap_or_else(|| {
                let full = if line == 0 {
                    message.to_string()
                } else {
                    format!("{message} at line {line} column {column}")
                };
                ("$".to_string(), full)
            });
        RegistryError::Parse {
            origin: origin.to_string(),
            location: Location::JsonPathAt {
                path: path.0,
                line,
                column,
            },
            message: path.1,
        }
    } else {
        let (mut line, mut column) = (line, column);
        if line == 0 {
            let lc = line_col(text, text.len());
            line = lc.0;
            column = lc.1;
        }
        let msg = message.split(" at line ").next().unwrap_or(message);
        RegistryError::at_line_col(origin, line, column.max(1), msg)
    }
}

fn kind(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// The JSON path and message of the first place where `v` does not have the expected shape; the
/// text and condition of an entry are checked where `kept` accepts its id.
fn find_shape_error(
    v: &serde_json::Value,
    kept: &dyn Fn(&str) -> bool,
) -> Option<(String, String)> {
    let root = match v.as_object() {
        Some(o) => o,
        None => return Some(("$".into(), format!("expected an object, found {}", kind(v)))),
    };
    if let Some(vi) = root.get("version info") {
        match vi.as_object() {
            None => {
                return Some((
                    "$.\"version info\"".into(),
                    format!("expected an object, found {}", kind(vi)),
                ))
            }
            Some(o) => {
                if let Some(av) = o.get("api version") {
                    if !av.is_string() {
                        return Some((
                            "$.\"version info\".\"api version\"".into(),
                            format!("expected a string, found {}", kind(av)),
                        ));
                    }
                }
            }
        }
    }
    let val = match root.get("validation") {
        None => return Some(("$".into(), "missing key `validation`".into())),
        Some(v) => v,
    };
    let val = match val.as_object() {
        None => {
            return Some((
                "$.validation".into(),
                format!("expected an object, found {}", kind(val)),
            ))
        }
        Some(o) => o,
    };
    for (scope, conds) in val {
        let p = format!("$.validation.{scope}");
        let conds = match conds.as_object() {
            None => return Some((p, format!("expected an object, found {}", kind(conds)))),
            Some(o) => o,
        };
        for (cond, entries) in conds {
            let p = format!("{p}.{cond}");
            let entries = match entries.as_array() {
                None => return Some((p, format!("expected an array, found {}", kind(entries)))),
                Some(a) => a,
            };
            for (i, e) in entries.iter().enumerate() {
                let p = format!("{p}[{i}]");
                let o = match e.as_object() {
                    None => return Some((p, format!("expected an object, found {}", kind(e)))),
                    Some(o) => o,
                };
                let mut checked = true;
                for key in ["vuid", "text"] {
                    match o.get(key) {
                        None => return Some((p, format!("missing key `{key}`"))),
                        Some(s) if checked && !s.is_string() => {
                            return Some((
                                format!("{p}.{key}"),
                                format!("expected a string, found {}", kind(s)),
                            ))
                        }
                        Some(s) => {
                            if key == "vuid" {
                                checked = s.as_str().is_some_and(kept);
                            }
                        }
                    }
                }
                if !checked {
                    continue;
                }
                if let Some(c) = o.get("condition") {
                    if !c.is_string() {
                        return Some((
                            format!("{p}.condition"),
                            format!("expected a string, found {}", kind(c)),
                        ));
                    }
                }
            }
        }
    }
    None
}
