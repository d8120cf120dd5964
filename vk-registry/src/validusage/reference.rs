//! The reading of validusage.json as it was before the scan and the raw texts, kept as the
//! reference the tests compare the reading with: every document it reads, the reading reads the
//! same, and every error it reports on a kept entry or on the JSON, the reading reports the same.

use super::{StrictDoc, StrictEntry};
use crate::error::{excerpt, line_col, Location, RegistryError};
use crate::vuid::{normalize_html, Condition, VuidRecord, VuidSet};
use std::collections::HashMap;

/// [`super::parse_where`] as it was.
pub fn parse_where(
    text: &str,
    origin: &str,
    keep: &dyn Fn(&str) -> bool,
) -> Result<VuidSet, RegistryError> {
    let doc: StrictDoc = match serde_json::from_str(text) {
        Ok(d) => d,
        Err(e) => return Err(locate_json_error(text, origin, e)),
    };
    let version = doc
        .version_info
        .and_then(|v| v.api_version)
        .map(|v| v.into_owned());
    let mut cond_cache: HashMap<&str, Condition> = HashMap::new();
    let mut records = Vec::with_capacity(32 * 1024);
    // Sort the outer keys so that errors (and duplicate resolution) are deterministic.
    let mut scopes: Vec<_> = doc.validation.iter().collect();
    scopes.sort_by(|a, b| a.0 .0.cmp(&b.0 .0));
    for (scope, conds) in scopes {
        let mut conds: Vec<_> = conds.iter().collect();
        conds.sort_by(|a, b| a.0 .0.cmp(&b.0 .0));
        for (cond_key, entries) in conds {
            let key: &str = &cond_key.0;
            // An id that is no VUID is kept, to be reported below.
            let kept =
                |e: &StrictEntry| crate::vuid::split_vuid(&e.vuid).is_none_or(|p| keep(p.scope));
            if !entries.iter().any(kept) {
                continue;
            }
            let cond = match cond_cache.get(key) {
                Some(c) => c.clone(),
                None => {
                    let c = Condition::parse(key).map_err(|(off, msg)| {
                        json_path_error(
                            text,
                            origin,
                            &format!("$.validation.{}", scope.0),
                            &format!(
                                "bad condition key `{}` at offset {off}: {msg}",
                                excerpt(key)
                            ),
                        )
                    })?;
                    cond_cache.insert(key, c.clone());
                    c
                }
            };
            for (i, e) in entries.iter().enumerate() {
                if !kept(e) {
                    continue;
                }
                let cond = match &e.condition {
                    Some(c) => Condition::parse(c).map_err(|(off, msg)| {
                        json_path_error(
                            text,
                            origin,
                            &format!("$.validation.{}.{}[{i}].condition", scope.0, key),
                            &format!("bad condition at offset {off}: {msg}"),
                        )
                    })?,
                    None => cond.clone(),
                };
                let rec =
                    VuidRecord::new(&e.vuid, cond, normalize_html(&e.text)).ok_or_else(|| {
                        json_path_error(
                            text,
                            origin,
                            &format!("$.validation.{}.{}[{i}].vuid", scope.0, key),
                            &format!("`{}` is not a VUID", excerpt(&e.vuid)),
                        )
                    })?;
                records.push(rec);
            }
        }
    }
    Ok(VuidSet::new(origin, version, records))
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

fn locate_json_error(text: &str, origin: &str, e: serde_json::Error) -> RegistryError {
    use serde_json::error::Category;
    match e.classify() {
        Category::Data => {
            // The syntax is fine; find the offending JSON path by walking a generic value.
            let (line, column) = (e.line(), e.column());
            let path = serde_json::from_str::<serde_json::Value>(text)
                .ok()
                .and_then(|v| find_shape_error(&v))
                .unwrap_or_else(|| ("$".to_string(), e.to_string()));
            RegistryError::Parse {
                origin: origin.to_string(),
                location: Location::JsonPathAt {
                    path: path.0,
                    line,
                    column,
                },
                message: path.1,
            }
        }
        _ => {
            let (mut line, mut column) = (e.line(), e.column());
            if line == 0 {
                let lc = line_col(text, text.len());
                line = lc.0;
                column = lc.1;
            }
            let msg = e.to_string();
            let msg = msg.split(" at line ").next().unwrap_or(&msg).to_string();
            RegistryError::at_line_col(origin, line, column.max(1), msg)
        }
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

/// The JSON path and message of the first place where `v` does not have the expected shape.
fn find_shape_error(v: &serde_json::Value) -> Option<(String, String)> {
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
                for key in ["vuid", "text"] {
                    match o.get(key) {
                        None => return Some((p, format!("missing key `{key}`"))),
                        Some(s) if !s.is_string() => {
                            return Some((
                                format!("{p}.{key}"),
                                format!("expected a string, found {}", kind(s)),
                            ))
                        }
                        _ => {}
                    }
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
