//! The common VUID record used for every source (validusage.json, man pages), its
//! condition expressions, and the text normalisation that makes texts comparable across formats.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Whether a VUID belongs to a command, a structure, or something else (SPIR-V rules, builtins).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ScopeKind {
    /// `vkSomething`.
    Command,
    /// `VkSomething`.
    Structure,
    /// Anything else (`StandaloneSpirv`, `RuntimeSpirv`, builtin variables...).
    Other,
}

impl ScopeKind {
    /// Classify a scope name by its prefix.
    pub fn of(scope: &str) -> ScopeKind {
        if scope.starts_with("vk") {
            ScopeKind::Command
        } else if scope.starts_with("Vk") {
            ScopeKind::Structure
        } else {
            ScopeKind::Other
        }
    }
}

/// A boolean expression over extension and `VK_VERSION_x_y` names.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Condition {
    /// Unconditional (`core`).
    Always,
    /// An extension, a `VK_VERSION_x_y` name, or (in vk.xml `depends`) a `Struct::feature` name.
    Ext(String),
    Not(Box<Condition>),
    All(Vec<Condition>),
    Any(Vec<Condition>),
}

impl Condition {
    /// Evaluate with a predicate telling which names are enabled.
    pub fn eval(&self, is_enabled: &dyn Fn(&str) -> bool) -> bool {
        match self {
            Condition::Always => true,
            Condition::Ext(n) => is_enabled(n),
            Condition::Not(c) => !c.eval(is_enabled),
            Condition::All(v) => v.iter().all(|c| c.eval(is_enabled)),
            Condition::Any(v) => v.iter().any(|c| c.eval(is_enabled)),
        }
    }

    /// Every name the expression mentions, in order of first appearance.
    pub fn names(&self) -> Vec<&str> {
        fn walk<'a>(c: &'a Condition, out: &mut Vec<&'a str>) {
            match c {
                Condition::Always => {}
                Condition::Ext(n) => {
                    if !out.contains(&n.as_str()) {
                        out.push(n)
                    }
                }
                Condition::Not(c) => walk(c, out),
                Condition::All(v) | Condition::Any(v) => v.iter().for_each(|c| walk(c, out)),
            }
        }
        let mut out = Vec::new();
        walk(self, &mut out);
        out
    }

    /// Parse the validusage / vk.xml `depends` syntax: `,` (or `|`) is OR, `+` (or `&`) is AND,
    /// `!` is NOT, parentheses group. `core` and the empty string mean [`Condition::Always`].
    /// On error returns the byte offset in `s` and a message.
    pub fn parse(s: &str) -> Result<Condition, (usize, String)> {
        let t = s.trim();
        if t.is_empty() || t == "core" {
            return Ok(Condition::Always);
        }
        let mut p = CondParser {
            s: s.as_bytes(),
            pos: 0,
            depth: 0,
        };
        let c = p.or()?;
        p.skip_ws();
        if p.pos < p.s.len() {
            return Err((
                p.pos,
                format!("unexpected `{}` in condition", p.s[p.pos] as char),
            ));
        }
        Ok(c)
    }

    fn fmt_prec(&self, f: &mut fmt::Formatter<'_>, prec: u8) -> fmt::Result {
        // prec: 0 = top/or, 1 = inside and, 2 = operand of not
        match self {
            Condition::Always => write!(f, "core"),
            Condition::Ext(n) => write!(f, "{n}"),
            Condition::Not(c) => {
                write!(f, "!(")?;
                c.fmt_prec(f, 0)?;
                write!(f, ")")
            }
            Condition::All(v) => {
                let paren = prec >= 2;
                if paren {
                    write!(f, "(")?;
                }
                for (i, c) in v.iter().enumerate() {
                    if i > 0 {
                        write!(f, "+")?;
                    }
                    c.fmt_prec(f, 1)?;
                }
                if paren {
                    write!(f, ")")?;
                }
                Ok(())
            }
            Condition::Any(v) => {
                let paren = prec >= 1;
                if paren {
                    write!(f, "(")?;
                }
                for (i, c) in v.iter().enumerate() {
                    if i > 0 {
                        write!(f, ",")?;
                    }
                    c.fmt_prec(f, 2)?;
                }
                if paren {
                    write!(f, ")")?;
                }
                Ok(())
            }
        }
    }
}

impl fmt::Display for Condition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.fmt_prec(f, 0)
    }
}

/// How deeply `(` and `!` may nest in a condition: the registry's own conditions nest a few levels;
/// the limit keeps the recursive parser (and the recursive drop of the tree) off the stack's end.
pub const MAX_CONDITION_DEPTH: usize = 64;

struct CondParser<'a> {
    s: &'a [u8],
    pos: usize,
    /// `(` and `!` open around the current position.
    depth: usize,
}

impl CondParser<'_> {
    fn skip_ws(&mut self) {
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }
    fn peek(&mut self) -> Option<u8> {
        self.skip_ws();
        self.s.get(self.pos).copied()
    }
    fn or(&mut self) -> Result<Condition, (usize, String)> {
        let mut items = vec![self.and()?];
        while matches!(self.peek(), Some(b',') | Some(b'|')) {
            self.pos += 1;
            items.push(self.and()?);
        }
        Ok(if items.len() == 1 {
            items.pop().unwrap()
        } else {
            Condition::Any(flatten(items, true))
        })
    }
    fn and(&mut self) -> Result<Condition, (usize, String)> {
        let mut items = vec![self.unary()?];
        while matches!(self.peek(), Some(b'+') | Some(b'&')) {
            self.pos += 1;
            items.push(self.unary()?);
        }
        Ok(if items.len() == 1 {
            items.pop().unwrap()
        } else {
            Condition::All(flatten(items, false))
        })
    }
    /// Enters one more level of `(` or `!` at the current position.
    fn descend(&mut self) -> Result<(), (usize, String)> {
        self.depth += 1;
        if self.depth > MAX_CONDITION_DEPTH {
            return Err((
                self.pos,
                format!("condition nests `(` and `!` deeper than {MAX_CONDITION_DEPTH} levels"),
            ));
        }
        Ok(())
    }
    fn unary(&mut self) -> Result<Condition, (usize, String)> {
        match self.peek() {
            Some(b'!') => {
                self.descend()?;
                self.pos += 1;
                let c = Condition::Not(Box::new(self.unary()?));
                self.depth -= 1;
                Ok(c)
            }
            Some(b'(') => {
                self.descend()?;
                let open = self.pos;
                self.pos += 1;
                let c = self.or()?;
                self.depth -= 1;
                if self.peek() != Some(b')') {
                    return Err((open, "unclosed `(` in condition".into()));
                }
                self.pos += 1;
                Ok(c)
            }
            Some(c) if c.is_ascii_alphanumeric() || c == b'_' => {
                let start = self.pos;
                while self.pos < self.s.len()
                    && (self.s[self.pos].is_ascii_alphanumeric()
                        || matches!(self.s[self.pos], b'_' | b':' | b'.'))
                {
                    self.pos += 1;
                }
                let name = std::str::from_utf8(&self.s[start..self.pos]).unwrap_or_default();
                Ok(Condition::Ext(name.to_string()))
            }
            Some(c) => Err((self.pos, format!("unexpected `{}` in condition", c as char))),
            None => Err((self.pos, "condition ends where a name was expected".into())),
        }
    }
}

fn flatten(items: Vec<Condition>, any: bool) -> Vec<Condition> {
    let mut out = Vec::with_capacity(items.len());
    for c in items {
        match c {
            Condition::Any(v) if any => out.extend(v),
            Condition::All(v) if !any => out.extend(v),
            c => out.push(c),
        }
    }
    out
}

/// One Valid Usage ID with its scope, condition and normalised text.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct VuidRecord {
    /// `VUID-vkCmdTraceRaysIndirectKHR-stride-03686`.
    pub id: String,
    /// `vkCmdTraceRaysIndirectKHR` or `VkStridedDeviceAddressRegionKHR`.
    pub scope: String,
    pub scope_kind: ScopeKind,
    /// `stride`; `None` (the string) when the VUID names no field.
    pub field: String,
    /// `03686`, or `parameter`, `recording`...
    pub tag: String,
    /// Whether the tag is not numeric (an implicit VUID).
    pub implicit: bool,
    pub condition: Condition,
    /// Normalised text (see [`normalize_html`]).
    pub text: String,
}

/// The parts of a VUID id.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VuidParts<'a> {
    pub scope: &'a str,
    pub field: &'a str,
    pub tag: &'a str,
}

/// The bytes a part of a VUID id may hold: ASCII letters and digits, `_`, `-` and `:`.
static VUID_BYTE: [bool; 256] = {
    let mut t = [false; 256];
    let mut b = 0;
    while b < 256 {
        let c = b as u8;
        t[b] = c.is_ascii_alphanumeric() || matches!(c, b'_' | b'-' | b':');
        b += 1;
    }
    t
};

/// Whether `s` can be a part of a VUID id ([`split_vuid`]): not empty, and only ASCII letters
/// and digits, `_`, `-` and `:`.
#[inline]
pub(crate) fn is_vuid_part(s: &str) -> bool {
    let b = s.as_bytes();
    #[cfg(target_arch = "x86_64")]
    if b.len() >= 16 {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86_64; each load reads 16 bytes of `b`, which has 16 or more.
        unsafe {
            let all_vuid_bytes = |at: usize| {
                let v = _mm_loadu_si128(b.as_ptr().add(at).cast());
                // `x` in `lo..=hi`, unsigned
                let within = |x: __m128i, lo: u8, hi: u8| {
                    let d = _mm_sub_epi8(x, _mm_set1_epi8(lo as i8));
                    _mm_cmpeq_epi8(_mm_min_epu8(d, _mm_set1_epi8((hi - lo) as i8)), d)
                };
                let letter = within(_mm_or_si128(v, _mm_set1_epi8(0x20)), b'a', b'z');
                let digit = within(v, b'0', b'9');
                let punct = _mm_or_si128(
                    _mm_cmpeq_epi8(v, _mm_set1_epi8(b'_' as i8)),
                    _mm_or_si128(
                        _mm_cmpeq_epi8(v, _mm_set1_epi8(b'-' as i8)),
                        _mm_cmpeq_epi8(v, _mm_set1_epi8(b':' as i8)),
                    ),
                );
                _mm_movemask_epi8(_mm_or_si128(_mm_or_si128(letter, digit), punct)) == 0xffff
            };
            let mut at = 0;
            while at + 16 < b.len() {
                if !all_vuid_bytes(at) {
                    return false;
                }
                at += 16;
            }
            // the last 16 bytes, which may overlap those checked
            return all_vuid_bytes(b.len() - 16);
        }
    }
    !b.is_empty() && b.iter().all(|&c| VUID_BYTE[c as usize])
}

/// Split `VUID-scope-field-tag` (or `VUID-scope-tag`); `None` if it is not a VUID id.
pub fn split_vuid(id: &str) -> Option<VuidParts<'_>> {
    let rest = id.strip_prefix("VUID-")?;
    let (scope, rest) = rest.split_once('-')?;
    if !is_vuid_part(scope) || !is_vuid_part(rest) {
        return None;
    }
    Some(match rest.rsplit_once('-') {
        Some((field, tag)) if !field.is_empty() && !tag.is_empty() => {
            VuidParts { scope, field, tag }
        }
        _ => VuidParts {
            scope,
            field: "None",
            tag: rest,
        },
    })
}

impl VuidRecord {
    /// Build a record from an id, a condition and an already normalised text.
    /// Returns `None` if `id` is not a well-formed VUID.
    pub fn new(id: &str, condition: Condition, text: String) -> Option<VuidRecord> {
        let p = split_vuid(id)?;
        Some(VuidRecord {
            id: id.to_string(),
            scope: p.scope.to_string(),
            scope_kind: ScopeKind::of(p.scope),
            field: p.field.to_string(),
            tag: p.tag.to_string(),
            implicit: !p.tag.bytes().all(|b| b.is_ascii_digit()),
            condition,
            text,
        })
    }
}

/// The VUIDs of one source (or of a union of sources).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct VuidSet {
    /// The path (or description) the set was read from.
    pub origin: String,
    /// The API version the source declares, such as `1.3.239`.
    pub version: Option<String>,
    /// Sorted by id, ids unique.
    pub records: Vec<VuidRecord>,
}

impl VuidSet {
    /// Sort by id and drop later duplicates (the first occurrence wins).
    pub fn new(
        origin: impl Into<String>,
        version: Option<String>,
        mut records: Vec<VuidRecord>,
    ) -> VuidSet {
        // stable sort keeps the first occurrence of equal ids first
        records.sort_by(|a, b| a.id.cmp(&b.id));
        records.dedup_by(|later, first| later.id == first.id);
        VuidSet {
            origin: origin.into(),
            version,
            records,
        }
    }

    /// The record with this id.
    pub fn get(&self, id: &str) -> Option<&VuidRecord> {
        self.records
            .binary_search_by(|r| r.id.as_str().cmp(id))
            .ok()
            .map(|i| &self.records[i])
    }

    /// The records whose scope is `scope` (a command's or structure's own VUIDs).
    pub fn for_scope<'a>(&'a self, scope: &'a str) -> impl Iterator<Item = &'a VuidRecord> + 'a {
        self.records.iter().filter(move |r| r.scope == scope)
    }

    pub fn len(&self) -> usize {
        self.records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// The ids, in order.
    pub fn ids(&self) -> Vec<&str> {
        self.records.iter().map(|r| r.id.as_str()).collect()
    }
}

// ---------------------------------------------------------------------------------------------
// Text normalisation

#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Html,
    Markdown,
}

struct Out {
    s: String,
    space: bool,
}

impl Out {
    fn push(&mut self, c: char) {
        if c.is_whitespace() {
            self.space = true;
            return;
        }
        if c == '\u{200b}' {
            return;
        }
        if self.space && !self.s.is_empty() {
            self.s.push(' ');
        }
        self.space = false;
        self.s.push(c);
    }
    /// Push a run of ASCII characters that holds no whitespace but single spaces between others.
    fn push_run(&mut self, t: &str) {
        if self.space && !self.s.is_empty() {
            self.s.push(' ');
        }
        self.space = false;
        self.s.push_str(t);
    }
    fn push_str(&mut self, t: &str) {
        for c in t.chars() {
            self.push(c);
        }
    }
}

/// Normalise an HTML fragment (validusage.json texts): tags removed, `<code>` kept as
/// backticks, entities decoded, whitespace collapsed, trimmed.
pub fn normalize_html(s: &str) -> String {
    let mut out = Out {
        s: String::with_capacity(s.len()),
        space: false,
    };
    run(s, Mode::Html, &mut out, 0);
    out.s
}

/// Normalise a Markdown fragment (man pages): like [`normalize_html`] for inline HTML, plus
/// links reduced to their text, `**strong**` markers and backslash escapes removed.
pub fn normalize_markdown(s: &str) -> String {
    let mut out = Out {
        s: String::with_capacity(s.len()),
        space: false,
    };
    run(s, Mode::Markdown, &mut out, 0);
    out.s
}

/// Normalise plain text: whitespace collapsed and trimmed.
pub fn normalize_plain(s: &str) -> String {
    let mut out = Out {
        s: String::with_capacity(s.len()),
        space: false,
    };
    out.push_str(s);
    out.s
}

/// Links nested deeper than this inside link texts are copied as text (each level recurses).
const MAX_LINK_NESTING: usize = 8;
/// A link's text or target longer than this is not a link: the bound keeps scanning for the
/// closing `]` or `)` from every `[` linear in the input. Real man pages stay far below it.
const MAX_LINK_SPAN: usize = 4096;
/// An HTML tag longer than this is text, for the same reason.
const MAX_TAG_LEN: usize = 4096;

/// Normalises `s` into `out`; `link_depth` is how many link texts enclose it.
fn run(s: &str, mode: Mode, out: &mut Out, link_depth: usize) {
    let b = s.as_bytes();
    let mut i = 0;
    let mut in_code = false;
    // fast path: copy runs of plain bytes
    while i < b.len() {
        let c = b[i];
        match c {
            b'<' => {
                if let Some(len) = tag_len(&b[i..]) {
                    let tag = &s[i + 1..i + len - 1];
                    let name_part = tag.trim_start_matches('/');
                    let name_end = name_part
                        .find(|c: char| !c.is_ascii_alphanumeric())
                        .unwrap_or(name_part.len());
                    let name = &name_part[..name_end];
                    if name.eq_ignore_ascii_case("code") {
                        out.push('`');
                    } else if is_block_tag(name) {
                        out.space = true;
                    }
                    i += len;
                    continue;
                }
                out.push('<');
                i += 1;
            }
            b'&' => {
                if let Some((ch, len)) = entity(&s[i..]) {
                    out.push(ch);
                    i += len;
                } else {
                    out.push('&');
                    i += 1;
                }
            }
            b'`' if mode == Mode::Markdown => {
                in_code = !in_code;
                out.push('`');
                i += 1;
            }
            b'\\'
                if mode == Mode::Markdown
                    && !in_code
                    && i + 1 < b.len()
                    && b[i + 1].is_ascii_punctuation() =>
            {
                out.push(b[i + 1] as char);
                i += 2;
            }
            b'*' if mode == Mode::Markdown && !in_code => {
                // emphasis markers (`**must**`, `*n*`); literal asterisks are escaped in Markdown
                i += 1;
            }
            b'[' if mode == Mode::Markdown && !in_code && link_depth < MAX_LINK_NESTING => {
                if let Some((text_end, link_end)) = md_link(b, i) {
                    run(&s[i + 1..text_end], mode, out, link_depth + 1);
                    i = link_end;
                } else {
                    out.push('[');
                    i += 1;
                }
            }
            _ if c < 0x80 => {
                // copy a run of ordinary ASCII bytes at once, single spaces between them included
                // (each one is the space that the whitespace before the next byte collapses to)
                let start = i;
                loop {
                    while i < b.len() && is_plain_byte(b[i]) {
                        i += 1;
                    }
                    if i > start
                        && b.get(i) == Some(&b' ')
                        && b.get(i + 1).is_some_and(|&n| is_plain_byte(n))
                    {
                        i += 2;
                        continue;
                    }
                    break;
                }
                if i > start {
                    out.push_run(&s[start..i]);
                } else {
                    out.push(c as char);
                    i += 1;
                }
            }
            _ => {
                let ch = s[i..].chars().next().unwrap_or('\u{fffd}');
                out.push(ch);
                i += ch.len_utf8();
            }
        }
    }
}

/// The bytes [`run`] copies as they are: ASCII graphic characters other than `<`, `&`, `` ` ``,
/// `\`, `*` and `[`.
static PLAIN_BYTE: [bool; 256] = {
    let mut t = [false; 256];
    let mut b = 0;
    while b < 256 {
        let c = b as u8;
        t[b] = c.is_ascii_graphic() && !matches!(c, b'<' | b'&' | b'`' | b'\\' | b'*' | b'[');
        b += 1;
    }
    t
};

#[inline]
fn is_plain_byte(c: u8) -> bool {
    PLAIN_BYTE[c as usize]
}

fn is_block_tag(name: &str) -> bool {
    [
        "p", "div", "ul", "ol", "li", "br", "table", "tr", "td", "th", "dl", "dt", "dd",
    ]
    .iter()
    .any(|t| name.eq_ignore_ascii_case(t))
}

/// Length of an HTML tag starting at `b[0] == '<'`, if it looks like one.
fn tag_len(b: &[u8]) -> Option<usize> {
    let first = *b.get(1)?;
    if !(first.is_ascii_alphabetic() || first == b'/' || first == b'!') {
        return None;
    }
    let mut quote = 0u8;
    for (k, &c) in b.iter().enumerate().take(MAX_TAG_LEN).skip(1) {
        if quote != 0 {
            if c == quote {
                quote = 0;
            }
        } else if c == b'"' || c == b'\'' {
            quote = c;
        } else if c == b'>' {
            return Some(k + 1);
        } else if c == b'<' {
            return None;
        }
    }
    None
}

/// Decode an entity at the start of `s` (which begins with `&`): the char and the length.
fn entity(s: &str) -> Option<(char, usize)> {
    let end = s.as_bytes().iter().take(12).position(|&c| c == b';')?;
    let body = &s[1..end];
    let ch = if let Some(num) = body.strip_prefix('#') {
        let v = if let Some(hex) = num.strip_prefix('x').or_else(|| num.strip_prefix('X')) {
            u32::from_str_radix(hex, 16).ok()?
        } else {
            num.parse::<u32>().ok()?
        };
        char::from_u32(v)?
    } else {
        match body {
            "amp" => '&',
            "lt" => '<',
            "gt" => '>',
            "quot" => '"',
            "apos" => '\'',
            "nbsp" => ' ',
            "rsquo" => '’',
            "lsquo" => '‘',
            "ldquo" => '“',
            "rdquo" => '”',
            "hellip" => '…',
            "times" => '×',
            "mdash" => '—',
            "ndash" => '–',
            _ => return None,
        }
    };
    Some((ch, end + 1))
}

/// A Markdown link `[text](target)` starting at `b[i] == '['`: returns the end of the text
/// (index of `]`) and the index after `)`.
fn md_link(b: &[u8], i: usize) -> Option<(usize, usize)> {
    let mut depth = 0usize;
    let mut k = i;
    let mut code = false;
    let close = loop {
        if k - i > MAX_LINK_SPAN {
            return None;
        }
        let c = *b.get(k)?;
        match c {
            b'`' => code = !code,
            b'\\' if !code => k += 1,
            b'[' if !code => depth += 1,
            b']' if !code => {
                depth -= 1;
                if depth == 0 {
                    break k;
                }
            }
            _ => {}
        }
        k += 1;
    };
    if b.get(close + 1) != Some(&b'(') {
        return None;
    }
    let mut k = close + 2;
    let mut depth = 1usize;
    // whether the target so far holds a `"` (a title, in which spaces are allowed)
    let mut quoted = false;
    while let Some(&c) = b.get(k) {
        if k - close > MAX_LINK_SPAN {
            return None;
        }
        match c {
            b'(' => depth += 1,
            b')' => {
                depth -= 1;
                if depth == 0 {
                    return Some((close, k + 1));
                }
            }
            b'"' => quoted = true,
            b' ' | b'\n' if depth == 1 && !quoted => return None,
            _ => {}
        }
        k += 1;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn condition_round_trip() {
        let s = "(VK_NV_ray_tracing,VK_KHR_ray_tracing_pipeline)+(VK_KHR_ray_tracing_pipeline)+!(VK_VERSION_1_3,VK_KHR_format_feature_flags2)";
        let c = Condition::parse(s).unwrap();
        assert_eq!(
            c.to_string(),
            "(VK_NV_ray_tracing,VK_KHR_ray_tracing_pipeline)+VK_KHR_ray_tracing_pipeline+!(VK_VERSION_1_3,VK_KHR_format_feature_flags2)"
        );
        assert_eq!(Condition::parse(&c.to_string()).unwrap(), c);
        let on = |n: &str| n == "VK_KHR_ray_tracing_pipeline";
        assert!(c.eval(&on));
        let on13 = |n: &str| n == "VK_KHR_ray_tracing_pipeline" || n == "VK_VERSION_1_3";
        assert!(!c.eval(&on13));
        assert_eq!(Condition::parse("core").unwrap(), Condition::Always);
        assert!(Condition::parse("(A,B").is_err());
        assert!(Condition::parse("A+").is_err());
    }

    #[test]
    fn conditions_nested_past_the_limit_are_refused_where_they_go_too_deep() {
        let d = MAX_CONDITION_DEPTH;
        let at_limit = format!("{}A{}", "(".repeat(d), ")".repeat(d));
        assert_eq!(
            Condition::parse(&at_limit).unwrap(),
            Condition::Ext("A".into())
        );
        let deep = format!("{}A{}", "(".repeat(100_000), ")".repeat(100_000));
        let (off, msg) = Condition::parse(&deep).unwrap_err();
        assert_eq!(off, d);
        assert!(msg.contains("deeper than 64"), "{msg}");
        let nots = "!".repeat(100_000) + "A";
        assert_eq!(Condition::parse(&nots).unwrap_err().0, d);
        // depth counts what is open, not how many groups there are
        let siblings = vec!["(A)"; 1000].join("+");
        assert!(Condition::parse(&siblings).is_ok());
    }

    #[test]
    fn long_or_deeply_nested_links_are_text() {
        assert_eq!(
            normalize_markdown("see [the text](#target) here"),
            "see the text here"
        );
        let long = format!("[{}](#t)", "a".repeat(MAX_LINK_SPAN + 1));
        assert!(normalize_markdown(&long).starts_with("[aaa"));
        // links nested past the limit keep their inner markup as text
        let n = MAX_LINK_NESTING + 2;
        let nested = format!("{}x{}", "[".repeat(n), "](#t)".repeat(n));
        let out = normalize_markdown(&nested);
        assert!(out.starts_with("[[x](#t)](#t)"), "{out}");
        let deep = format!("{}x{}", "[".repeat(10_000), "](#t)".repeat(10_000));
        assert!(normalize_markdown(&deep).contains('x'));
        let unclosed = "[a".repeat(5_000);
        assert_eq!(normalize_markdown(&unclosed), unclosed);
    }

    #[test]
    fn runs_of_words_keep_single_spaces_and_collapse_the_others() {
        assert_eq!(normalize_html("a b  c\td \n e "), "a b c d e");
        assert_eq!(normalize_html("  x y\u{200b} z"), "x y z");
        assert_eq!(normalize_html("x\u{200b}y"), "xy");
        assert_eq!(normalize_html("a &amp; b &gt;c"), "a & b >c");
        assert_eq!(normalize_html("a <p>b</p> c<br>d<DIV>e"), "a b c d e");
        assert_eq!(normalize_html("x<b>y</b> <CODE>z</Code> w"), "xy `z` w");
        assert_eq!(normalize_markdown("a *b* c \\*d [e](#f) g"), "a b c *d e g");
    }

    #[test]
    fn vuid_parts_are_recognised_at_every_length() {
        let scalar = |s: &str| {
            !s.is_empty()
                && s.bytes()
                    .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b':'))
        };
        let alphabet: Vec<char> = (0u8..128)
            .map(char::from)
            .chain(['é', '\u{200b}'])
            .collect();
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for len in 0..70 {
            for _ in 0..400 {
                // mostly VUID bytes, one other byte now and then
                let s: String = (0..len)
                    .map(|_| {
                        seed ^= seed << 13;
                        seed ^= seed >> 7;
                        seed ^= seed << 17;
                        if seed % 23 == 0 {
                            alphabet[(seed >> 8) as usize % alphabet.len()]
                        } else {
                            b"aZ09_-:"[(seed >> 8) as usize % 7] as char
                        }
                    })
                    .collect();
                assert_eq!(is_vuid_part(&s), scalar(&s), "{s:?}");
            }
        }
    }

    #[test]
    fn split_ids() {
        let p = split_vuid("VUID-vkCmdTraceRaysIndirectKHR-stride-03686").unwrap();
        assert_eq!(
            (p.scope, p.field, p.tag),
            ("vkCmdTraceRaysIndirectKHR", "stride", "03686")
        );
        let p = split_vuid("VUID-vkCmdTraceRaysIndirectKHR-renderpass").unwrap();
        assert_eq!((p.field, p.tag), ("None", "renderpass"));
        assert!(split_vuid("VUID-x").is_none());
        assert!(split_vuid("vkFoo-a-1").is_none());
    }

    #[test]
    fn normalisation_agrees_across_formats() {
        let html = "The <a href=\"#features-x\"><code>x</code></a> feature <strong class=\"purple\">must</strong> be &gt; the view&#8217;s <a href=\"#VkSampler\">VkSampler</a>";
        let md = "The [`x`](#features-x) feature **must** be \\> the view’s [VkSampler](https://e.org/VkSampler.html)";
        assert_eq!(normalize_html(html), normalize_markdown(md));
        assert_eq!(
            normalize_html(html),
            "The `x` feature must be > the view’s VkSampler"
        );
        assert_eq!(normalize_markdown("a\\_b  \n  `p`\\[i\\]"), "a_b `p`[i]");
        assert_eq!(normalize_plain("  a \n b "), "a b");
    }
}
