//! The text printed by the `rtconf registry` subcommands: VUID lists (plain and JSON), diffs
//! between two VUID sets, and a readable view of a registry entry.

use crate::error::RegistryError;
use crate::vuid::{VuidRecord, VuidSet};
use crate::xml::Registry;
use std::fmt::Write;

fn selected<'a>(
    set: &'a VuidSet,
    command: Option<&'a str>,
) -> impl Iterator<Item = &'a VuidRecord> + 'a {
    set.records
        .iter()
        .filter(move |r| command.unwrap_or(&r.scope) == r.scope)
}

/// One VUID id per line, sorted; with `command`, only the VUIDs whose scope is that command.
pub fn vuids_plain(set: &VuidSet, command: Option<&str>) -> String {
    let mut out = String::new();
    for r in selected(set, command) {
        out.push_str(&r.id);
        out.push('\n');
    }
    out
}

/// A JSON array of `{id, scope, implicit, condition, text}` objects, sorted by id.
pub fn vuids_json(set: &VuidSet, command: Option<&str>) -> String {
    let items: Vec<serde_json::Value> = selected(set, command)
        .map(|r| {
            serde_json::json!({
                "id": r.id,
                "scope": r.scope,
                "implicit": r.implicit,
                "condition": r.condition.to_string(),
                "text": r.text,
            })
        })
        .collect();
    let mut s = serde_json::to_string_pretty(&items).unwrap_or_else(|_| "[]".into());
    s.push('\n');
    s
}

/// What [`diff_with`] compares.
#[derive(Debug, Clone, Copy, Default)]
pub struct DiffOptions<'a> {
    /// Only this command's VUIDs.
    pub command: Option<&'a str>,
    /// Leave out VUIDs whose normalised text is the same and only their condition differs.
    pub ignore_conditions: bool,
}

/// The differences from `a` to `b`: VUIDs added (only in `b`), removed (only in `a`), and
/// those whose normalised text or condition changed.
pub fn diff(a: &VuidSet, b: &VuidSet, command: Option<&str>) -> String {
    diff_with(
        a,
        b,
        &DiffOptions {
            command,
            ignore_conditions: false,
        },
    )
}

/// [`diff`] with options; with `ignore_conditions` the header says how many condition-only changes
/// were left out.
pub fn diff_with(a: &VuidSet, b: &VuidSet, options: &DiffOptions) -> String {
    let command = options.command;
    let left: Vec<&VuidRecord> = selected(a, command).collect();
    let right: Vec<&VuidRecord> = selected(b, command).collect();
    let mut condition_only = 0usize;
    let (mut added, mut removed, mut changed) = (Vec::new(), Vec::new(), Vec::new());
    let (mut i, mut j) = (0, 0);
    while i < left.len() || j < right.len() {
        match (left.get(i), right.get(j)) {
            (Some(l), Some(r)) if l.id == r.id => {
                if l.text == r.text && l.condition != r.condition && options.ignore_conditions {
                    condition_only += 1;
                } else if l.text != r.text || l.condition != r.condition {
                    changed.push((*l, *r));
                }
                i += 1;
                j += 1;
            }
            (Some(l), Some(r)) if l.id < r.id => {
                removed.push(*l);
                i += 1;
            }
            (Some(_), Some(r)) => {
                added.push(*r);
                j += 1;
            }
            (Some(l), None) => {
                removed.push(*l);
                i += 1;
            }
            (None, Some(r)) => {
                added.push(*r);
                j += 1;
            }
            (None, None) => break,
        }
    }
    let mut out = String::new();
    let ver = |s: &VuidSet| {
        s.version
            .clone()
            .map(|v| format!(" ({v})"))
            .unwrap_or_default()
    };
    let _ = writeln!(out, "--- {}{}", a.origin, ver(a));
    let _ = writeln!(out, "+++ {}{}", b.origin, ver(b));
    let _ = writeln!(
        out,
        "added: {}, removed: {}, changed: {}{}",
        added.len(),
        removed.len(),
        changed.len(),
        if options.ignore_conditions {
            format!(" ({condition_only} changed in their condition only, left out)")
        } else {
            String::new()
        }
    );
    if !added.is_empty() {
        let _ = writeln!(out, "\nadded:");
        for r in &added {
            let _ = writeln!(out, "+ {}", r.id);
        }
    }
    if !removed.is_empty() {
        let _ = writeln!(out, "\nremoved:");
        for r in &removed {
            let _ = writeln!(out, "- {}", r.id);
        }
    }
    if !changed.is_empty() {
        let _ = writeln!(out, "\nchanged:");
        for (l, r) in &changed {
            let _ = writeln!(out, "~ {}", l.id);
            if l.condition != r.condition && !options.ignore_conditions {
                let _ = writeln!(out, "    condition - {}", l.condition);
                let _ = writeln!(out, "    condition + {}", r.condition);
            }
            if l.text != r.text {
                let _ = writeln!(out, "    text - {}", l.text);
                let _ = writeln!(out, "    text + {}", r.text);
            }
        }
    }
    out
}

/// A readable description of a command, a type (structure, union, handle, enum, bitmask...)
/// or an enum value.
pub fn show(reg: &Registry, name: &str) -> Result<String, RegistryError> {
    reg.describe(name)
        .ok_or_else(|| RegistryError::UnknownName {
            name: name.to_string(),
        })
}
