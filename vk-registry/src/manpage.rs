//! Vulkan man pages in three text formats — the Markdown rendering of the HTML page
//! (`- [](#VUID-x)VUID-x` items), pandoc Markdown with raw `<a id="VUID-x">` anchors, and plain
//! text (a VUID alone on its line) — detected automatically, yielding the VUIDs each page
//! defines and the page's C prototype.

use crate::error::{excerpt, read_to_string, RegistryError};
use crate::vuid::{
    normalize_markdown, normalize_plain, split_vuid, Condition, VuidRecord, VuidSet,
};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// What a man page says about its command (or structure).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ManPage {
    /// The command (or structure) the page documents.
    pub command: String,
    /// The C prototype, whitespace collapsed (empty when the page shows none).
    pub prototype: String,
}

/// The text formats a man page can come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ManPageFormat {
    /// Markdown rendering of the HTML page: `- [](#VUID-x)VUID-x`.
    HtmlMarkdown,
    /// pandoc Markdown with raw `<a href="#VUID-x" id="VUID-x"></a>` anchors.
    PandocMarkdown,
    /// Plain text: each VUID alone on a line, followed by its text.
    PlainText,
}

/// Guess the format of a man page; `None` if it looks like none of them.
pub fn detect_format(text: &str) -> Option<ManPageFormat> {
    if text.contains("[](#VUID-") {
        Some(ManPageFormat::HtmlMarkdown)
    } else if text.contains("id=\"VUID-") || text.contains("id='VUID-") {
        Some(ManPageFormat::PandocMarkdown)
    } else if text.lines().any(|l| is_vuid_token(l.trim())) {
        Some(ManPageFormat::PlainText)
    } else if text.starts_with("# ") && text.contains("Manual Page") {
        Some(ManPageFormat::HtmlMarkdown)
    } else {
        None
    }
}

/// Read a man page file.
pub fn load(path: &Path) -> Result<(ManPage, VuidSet), RegistryError> {
    let text = read_to_string(path)?;
    parse(&text, &path.display().to_string())
}

/// Parse a man page; `origin` names it in errors and in the set.
pub fn parse(text: &str, origin: &str) -> Result<(ManPage, VuidSet), RegistryError> {
    let format = detect_format(text).ok_or_else(|| {
        RegistryError::at_line_col(
            origin,
            1,
            1,
            "not a recognised man page format (no VUID anchors or entries)",
        )
    })?;
    let entries = match format {
        ManPageFormat::HtmlMarkdown => entries_html_md(text, origin)?,
        ManPageFormat::PandocMarkdown => entries_pandoc(text, origin)?,
        ManPageFormat::PlainText => entries_plain(text, origin)?,
    };
    let mut records = Vec::with_capacity(entries.len());
    for (off, id, body) in entries {
        let norm = match format {
            ManPageFormat::PlainText => normalize_plain(&body),
            _ => normalize_markdown(&body),
        };
        if norm.is_empty() {
            return Err(RegistryError::at_offset(
                origin,
                text,
                off,
                format!("{id} has no text (truncated page?)"),
            ));
        }
        let rec = VuidRecord::new(&id, Condition::Always, norm).ok_or_else(|| {
            RegistryError::at_offset(
                origin,
                text,
                off,
                format!("`{}` is not a VUID", excerpt(&id)),
            )
        })?;
        records.push(rec);
    }
    let command = page_name(text, format)
        .or_else(|| records.first().map(|r| r.scope.clone()))
        .unwrap_or_default();
    let prototype = prototype(text, &command, origin)?;
    Ok((
        ManPage { command, prototype },
        VuidSet::new(origin, None, records),
    ))
}

fn is_vuid_token(s: &str) -> bool {
    s.starts_with("VUID-") && !s.contains(char::is_whitespace) && split_vuid(s).is_some()
}

fn page_name(text: &str, format: ManPageFormat) -> Option<String> {
    let first = text.lines().find(|l| !l.trim().is_empty())?.trim();
    let name = match format {
        ManPageFormat::PlainText => first,
        _ => {
            let t = first.trim_start_matches('#').trim();
            t.split(['(', ' ']).next().unwrap_or(t)
        }
    };
    if !name.is_empty() && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
        Some(name.to_string())
    } else {
        None
    }
}

/// The longest text a prototype's line may hold before the name (`VKAPI_ATTR VkResult VKAPI_CALL` is
/// 30 bytes); longer is prose, and the bound keeps the search linear in the page.
const MAX_RETURN_TYPE_LEN: usize = 128;

/// The C prototype of `name`: the line holding `name(` through the closing `);`
/// (or `typedef struct name {` through `} name;`).
fn prototype(text: &str, name: &str, origin: &str) -> Result<String, RegistryError> {
    if name.is_empty() {
        return Ok(String::new());
    }
    let call = format!("{name}(");
    let mut search = 0;
    // the start of the line holding the current candidate, found from the previous candidate on
    let (mut line_start, mut scanned) = (0, 0);
    while let Some(p) = text[search..].find(&call) {
        let at = search + p;
        search = at + call.len();
        if let Some(nl) = text[scanned..at].rfind('\n') {
            line_start = scanned + nl + 1;
        }
        scanned = at;
        let before = text[line_start..at].trim();
        // a return type must precede the name on its line (skips prose mentions)
        if before.is_empty()
            || before.len() > MAX_RETURN_TYPE_LEN
            || !before
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'*' || b == b' ')
        {
            continue;
        }
        let rest = &text[at..];
        let end = rest.find(");");
        let fence = rest.find("```");
        return match end {
            Some(e) if fence.unwrap_or(usize::MAX) > e => {
                Ok(collapse_proto(&text[line_start..at + e + 2]))
            }
            _ => Err(RegistryError::at_offset(
                origin,
                text,
                at,
                format!("prototype of {name} is not closed by `);` (truncated page?)"),
            )),
        };
    }
    let typedef = format!("typedef struct {name} {{");
    if let Some(at) = text.find(&typedef) {
        let close = format!("}} {name};");
        return match text[at..].find(&close) {
            Some(e) => Ok(collapse_proto(&text[at..at + e + close.len()])),
            None => Err(RegistryError::at_offset(
                origin,
                text,
                at,
                format!("definition of {name} is not closed (truncated page?)"),
            )),
        };
    }
    Ok(String::new())
}

fn collapse_proto(s: &str) -> String {
    let c = normalize_plain(s);
    c.replace("( ", "(").replace(" )", ")").replace(" ,", ",")
}

type Entry = (usize, String, String);

/// Offset of each line start, with the line text (without the newline).
fn lines_with_offsets(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut off = 0;
    for l in text.split_inclusive('\n') {
        out.push((off, l.trim_end_matches(['\n', '\r'])));
        off += l.len();
    }
    out
}

fn indent(l: &str) -> usize {
    l.len() - l.trim_start().len()
}

/// The body of an entry: the rest of its first line plus the following lines that are indented
/// (or blank), stopping at the first non-blank line with less indentation than `min_indent`.
fn body_from(
    lines: &[(usize, &str)],
    first_rest: &str,
    next: usize,
    min_indent: usize,
) -> (String, usize) {
    let mut body = String::from(first_rest);
    let mut k = next;
    while k < lines.len() {
        let l = lines[k].1;
        if !l.trim().is_empty() && indent(l) < min_indent {
            break;
        }
        body.push('\n');
        body.push_str(l);
        k += 1;
    }
    (body, k)
}

fn entries_html_md(text: &str, origin: &str) -> Result<Vec<Entry>, RegistryError> {
    let lines = lines_with_offsets(text);
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let (off, l) = lines[i];
        let ind = indent(l);
        let t = &l[ind..];
        if let Some(rest) = t.strip_prefix("- [](#VUID-") {
            let close = rest.find(')').ok_or_else(|| {
                RegistryError::at_offset(
                    origin,
                    text,
                    off + ind,
                    "VUID anchor is not closed by `)` (truncated page?)",
                )
            })?;
            let id = format!("VUID-{}", &rest[..close]);
            let mut after = &rest[close + 1..];
            after = after.trim_start();
            if let Some(r) = after.strip_prefix(id.as_str()) {
                after = r;
            }
            let (body, next) = body_from(&lines, after, i + 1, ind + 1);
            out.push((off + ind, id, body));
            i = next;
        } else {
            i += 1;
        }
    }
    Ok(out)
}

fn entries_pandoc(text: &str, origin: &str) -> Result<Vec<Entry>, RegistryError> {
    let lines = lines_with_offsets(text);
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let (off, l) = lines[i];
        let ind = indent(l);
        let t = &l[ind..];
        if !(t.starts_with("- <a") && (t.len() == 4 || t.as_bytes()[4].is_ascii_whitespace())) {
            i += 1;
            continue;
        }
        // the anchor may span several lines: find `</a>` from here on
        let start = off + ind + 2;
        let rest = &text[start..];
        let end = rest.find("</a>").ok_or_else(|| {
            RegistryError::at_offset(
                origin,
                text,
                start,
                "anchor `<a` is not closed by `</a>` (truncated page?)",
            )
        })?;
        let tag = &rest[..end];
        let Some(idp) = tag
            .find("id=\"VUID-")
            .map(|p| p + 4)
            .or_else(|| tag.find("id='VUID-").map(|p| p + 4))
        else {
            i += 1;
            continue;
        };
        let q = tag.as_bytes()[idp - 1];
        let id_end = tag[idp..].find(q as char).ok_or_else(|| {
            RegistryError::at_offset(
                origin,
                text,
                start + idp,
                "unterminated id attribute (truncated page?)",
            )
        })?;
        let id = tag[idp..idp + id_end].to_string();
        let after_abs = start + end + 4;
        // find the line holding `</a>`
        let mut k = i;
        while k + 1 < lines.len() && lines[k + 1].0 <= start + end {
            k += 1;
        }
        let line_end = lines[k].0 + lines[k].1.len();
        let mut first_rest = text[after_abs..line_end.max(after_abs)].trim_start();
        let mut next = k + 1;
        if first_rest.is_empty() && next < lines.len() && lines[next].1.trim() == id {
            // displayed id on its own line
            first_rest = "";
            next += 1;
        } else if let Some(r) = first_rest.strip_prefix(id.as_str()) {
            first_rest = r;
        }
        let (body, n) = body_from(&lines, first_rest, next, ind + 1);
        out.push((off + ind, id, body));
        i = n;
    }
    Ok(out)
}

const PLAIN_HEADINGS: &[&str] = &[
    "Valid Usage",
    "Valid Usage (Implicit)",
    "Host Synchronization",
    "Command Properties",
    "Return Codes",
    "See Also",
    "Document Notes",
    "Copyright",
    "Parameters",
    "Description",
    "C Specification",
];

fn entries_plain(text: &str, _origin: &str) -> Result<Vec<Entry>, RegistryError> {
    let lines = lines_with_offsets(text);
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let (off, l) = lines[i];
        let t = l.trim();
        if !is_vuid_token(t) {
            i += 1;
            continue;
        }
        let mut body = String::new();
        let mut k = i + 1;
        while k < lines.len() {
            let lt = lines[k].1.trim();
            if is_vuid_token(lt) || PLAIN_HEADINGS.contains(&lt) {
                break;
            }
            body.push('\n');
            body.push_str(lt);
            k += 1;
        }
        out.push((off + indent(l), t.to_string(), body));
        i = k;
    }
    Ok(out)
}
