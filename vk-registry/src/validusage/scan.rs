//! A quick reading of validusage.json in its usual form: one pass over the text that checks it is
//! JSON and picks out the kept entries, with no value built for the others.
//!
//! It reads only what it is sure serde_json reads the same way, and gives up (`None`) on anything
//! else: a document it reads holds no JSON error, no key twice, and every key, id and version as
//! it is written (no escape), so that [`super::parse_where_by_serde`] would find the same entries
//! in it. What it gives up on, that reading reads: an escape in a key, an id or the version; a
//! `\u` escape anywhere; a key given twice; a member the form does not name whose value is not a
//! string, an integer, `true`, `false` or `null`; a text, an id, a version or a condition that is
//! no string (a condition may be `null`); a `version info` that is no object; an entry without an
//! id or a text; and any error of JSON syntax or shape.

use super::{Group, Kept, ScopeFilter};
use std::borrow::Cow;

/// The version and the kept entries of a document.
pub(super) struct Scanned<'a> {
    pub(super) version: Option<&'a str>,
    pub(super) groups: Vec<Group<'a>>,
}

/// Read `text`, keeping the entries `filter` keeps; `None` where the document is not in the
/// usual form (see the module's documentation).
pub(super) fn scan<'a>(text: &'a str, filter: &mut ScopeFilter<'_, 'a>) -> Option<Scanned<'a>> {
    let mut s = Scan {
        t: text,
        b: text.as_bytes(),
        i: 0,
    };
    s.open(b'{')?;
    let (mut version, mut seen_version) = (None, false);
    let mut groups = None;
    if !s.close(b'}')? {
        loop {
            match s.key()? {
                "version info" => {
                    if std::mem::replace(&mut seen_version, true) {
                        return None;
                    }
                    version = s.version_info()?;
                }
                "validation" => {
                    if groups.is_some() {
                        return None;
                    }
                    groups = Some(s.validation(filter)?);
                }
                _ => s.skip_value()?,
            }
            if !s.next(b'}')? {
                break;
            }
        }
    }
    s.ws();
    if s.i != s.b.len() {
        return None;
    }
    Some(Scanned {
        version,
        groups: groups?,
    })
}

struct Scan<'a> {
    t: &'a str,
    b: &'a [u8],
    /// The next byte to read.
    i: usize,
}

impl<'a> Scan<'a> {
    /// Skip JSON whitespace.
    #[inline]
    fn ws(&mut self) {
        if self.b.get(self.i).is_some_and(|&c| is_ws(c)) {
            self.i = skip_ws(self.b, self.i + 1);
        }
    }

    /// The next byte after whitespace.
    #[inline]
    fn peek(&mut self) -> Option<u8> {
        self.ws();
        self.b.get(self.i).copied()
    }

    /// Read `c` (after whitespace).
    #[inline]
    fn open(&mut self, c: u8) -> Option<()> {
        (self.peek()? == c).then(|| self.i += 1)
    }

    /// Just after an opening bracket: whether the object or array closes at once (with `c`).
    #[inline]
    fn close(&mut self, c: u8) -> Option<bool> {
        let closes = self.peek()? == c;
        if closes {
            self.i += 1;
        }
        Some(closes)
    }

    /// After a member or element: whether another follows (`,`) or the object or array closes
    /// (with `c`); `None` on anything else.
    #[inline]
    fn next(&mut self, c: u8) -> Option<bool> {
        let p = self.peek()?;
        self.i += 1;
        if p == b',' {
            Some(true)
        } else if p == c {
            Some(false)
        } else {
            None
        }
    }

    /// An object's key with no escape and its `:`.
    #[inline]
    fn key(&mut self) -> Option<&'a str> {
        let k = self.plain_str()?;
        self.open(b':')?;
        Some(k)
    }

    /// A string with no escape (after whitespace): its content.
    #[inline]
    fn plain_str(&mut self) -> Option<&'a str> {
        self.open(b'"')?;
        let start = self.i;
        let end = find_special(self.b, start);
        if self.b.get(end) != Some(&b'"') {
            return None;
        }
        self.i = end + 1;
        Some(&self.t[start..end])
    }

    /// A string whose escapes are all one character (no `\u`), after whitespace: its raw JSON.
    #[inline]
    fn raw_str(&mut self) -> Option<&'a str> {
        self.open(b'"')?;
        let start = self.i - 1;
        self.i = string_end(self.b, self.i)? + 1;
        Some(&self.t[start..self.i])
    }

    /// Skip a value that is a string, an integer, `true`, `false` or `null`.
    fn skip_value(&mut self) -> Option<()> {
        match self.peek()? {
            b'"' => self.raw_str().map(drop),
            b'-' | b'0'..=b'9' => {
                // `-?(0|[1-9][0-9]*)`, not followed by what would make it another number
                let mut i = self.i + usize::from(self.b[self.i] == b'-');
                match self.b.get(i)? {
                    b'0' => i += 1,
                    b'1'..=b'9' => {
                        while self.b.get(i).is_some_and(u8::is_ascii_digit) {
                            i += 1;
                        }
                    }
                    _ => return None,
                }
                if matches!(self.b.get(i), Some(b'0'..=b'9' | b'.' | b'e' | b'E')) {
                    return None;
                }
                self.i = i;
                Some(())
            }
            _ => {
                let word = ["true", "false", "null"]
                    .into_iter()
                    .find(|w| self.b[self.i..].starts_with(w.as_bytes()))?;
                self.i += word.len();
                Some(())
            }
        }
    }

    /// The `version info` object: its `api version`.
    fn version_info(&mut self) -> Option<Option<&'a str>> {
        self.open(b'{')?;
        let (mut api, mut seen) = (None, false);
        if !self.close(b'}')? {
            loop {
                if self.key()? == "api version" {
                    if std::mem::replace(&mut seen, true) {
                        return None;
                    }
                    api = Some(self.plain_str()?);
                } else {
                    self.skip_value()?;
                }
                if !self.next(b'}')? {
                    break;
                }
            }
        }
        Some(api)
    }

    /// The `validation` object: the groups of the kept entries.
    fn validation(&mut self, filter: &mut ScopeFilter<'_, 'a>) -> Option<Vec<Group<'a>>> {
        self.open(b'{')?;
        let mut groups = Vec::new();
        let mut scopes = Vec::new();
        let mut keys: Vec<&str> = Vec::new();
        if self.close(b'}')? {
            return Some(groups);
        }
        loop {
            let scope = self.key()?;
            scopes.push(scope);
            self.open(b'{')?;
            keys.clear();
            if !self.close(b'}')? {
                loop {
                    let key = self.key()?;
                    keys.push(key);
                    let kept = self.entries(filter)?;
                    if !kept.is_empty() {
                        groups.push(Group { scope, key, kept });
                    }
                    if !self.next(b'}')? {
                        break;
                    }
                }
            }
            if has_twice(&mut keys) {
                return None;
            }
            if !self.next(b'}')? {
                break;
            }
        }
        if has_twice(&mut scopes) {
            return None;
        }
        Some(groups)
    }

    /// An array of entries: the kept ones.
    fn entries(&mut self, filter: &mut ScopeFilter<'_, 'a>) -> Option<Vec<Kept<'a>>> {
        self.open(b'[')?;
        let mut kept = Vec::new();
        if self.close(b']')? {
            return Some(kept);
        }
        let mut index = 0;
        loop {
            let e = self.entry(index)?;
            if filter.keeps(e.vuid) {
                kept.push(e);
            }
            index += 1;
            if !self.next(b']')? {
                break;
            }
        }
        Some(kept)
    }

    /// An entry object.
    fn entry(&mut self, index: usize) -> Option<Kept<'a>> {
        self.open(b'{')?;
        let (mut vuid, mut text, mut condition) = (None, None, None);
        if self.close(b'}')? {
            return None;
        }
        loop {
            match self.key()? {
                "vuid" => {
                    if vuid.replace(self.plain_str()?).is_some() {
                        return None;
                    }
                }
                "text" => {
                    if text.replace(self.raw_str()?).is_some() {
                        return None;
                    }
                }
                "condition" => {
                    let c = if self.peek()? == b'n' {
                        self.skip_value()?;
                        None
                    } else {
                        Some(self.raw_str()?)
                    };
                    if condition.replace(c).is_some() {
                        return None;
                    }
                }
                _ => self.skip_value()?,
            }
            if !self.next(b'}')? {
                break;
            }
        }
        Some(Kept {
            index,
            vuid: vuid?,
            text: text?,
            condition: condition.flatten(),
        })
    }
}

/// Whether a key is given twice (sorting the keys).
fn has_twice(keys: &mut [&str]) -> bool {
    keys.len() > 1 && {
        keys.sort_unstable();
        keys.windows(2).any(|w| w[0] == w[1])
    }
}

/// The string the raw JSON string `raw` holds, whose escapes are all one character (no `\u`), as
/// the scan reads them.
pub(super) fn unescape(raw: &str) -> Cow<'_, str> {
    let inner = &raw[1..raw.len() - 1];
    let Some(first) = inner.find('\\') else {
        return Cow::Borrowed(inner);
    };
    let mut out = String::with_capacity(inner.len());
    let mut rest = inner;
    let mut at = first;
    loop {
        out.push_str(&rest[..at]);
        out.push(match rest.as_bytes()[at + 1] {
            b'b' => '\u{8}',
            b'f' => '\u{c}',
            b'n' => '\n',
            b'r' => '\r',
            b't' => '\t',
            // `"`, `\\`, `/`
            c => char::from(c),
        });
        rest = &rest[at + 2..];
        match rest.find('\\') {
            Some(k) => at = k,
            None => break,
        }
    }
    out.push_str(rest);
    Cow::Owned(out)
}

/// JSON whitespace, as serde_json reads it.
#[inline]
fn is_ws(c: u8) -> bool {
    matches!(c, b' ' | b'\n' | b'\t' | b'\r')
}

/// The index of the first byte from `i` on that is no whitespace (or the length).
fn skip_ws(b: &[u8], mut i: usize) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86_64; each load reads the 16 bytes from `i`, within `b`.
        unsafe {
            let (space, nl) = (_mm_set1_epi8(b' ' as i8), _mm_set1_epi8(b'\n' as i8));
            let (tab, cr) = (_mm_set1_epi8(b'\t' as i8), _mm_set1_epi8(b'\r' as i8));
            while i + 16 <= b.len() {
                let v = _mm_loadu_si128(b.as_ptr().add(i).cast());
                let ws = _mm_or_si128(
                    _mm_or_si128(_mm_cmpeq_epi8(v, space), _mm_cmpeq_epi8(v, nl)),
                    _mm_or_si128(_mm_cmpeq_epi8(v, tab), _mm_cmpeq_epi8(v, cr)),
                );
                let other = !_mm_movemask_epi8(ws) & 0xffff;
                if other != 0 {
                    return i + other.trailing_zeros() as usize;
                }
                i += 16;
            }
        }
    }
    while i < b.len() && is_ws(b[i]) {
        i += 1;
    }
    i
}

/// The index of the `"` that ends the JSON string whose content starts at `i`, if the string holds
/// no control character and its escapes are all one character (no `\u`).
fn string_end(b: &[u8], mut i: usize) -> Option<usize> {
    let simple_escape = |c: u8| matches!(c, b'"' | b'\\' | b'/' | b'b' | b'f' | b'n' | b'r' | b't');
    #[cfg(target_arch = "x86_64")]
    'chunks: while i + 16 <= b.len() {
        let mut mask = special_mask(b, i);
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            match b[i + k] {
                b'"' => return Some(i + k),
                b'\\' => {
                    if !simple_escape(*b.get(i + k + 1)?) {
                        return None;
                    }
                    if k == 15 {
                        // the escaped byte opens the next chunk
                        i += 17;
                        continue 'chunks;
                    }
                    mask &= u32::MAX << (k + 2);
                }
                _ => return None,
            }
        }
        i += 16;
    }
    while i < b.len() {
        match b[i] {
            b'"' => return Some(i),
            b'\\' => {
                if !simple_escape(*b.get(i + 1)?) {
                    return None;
                }
                i += 2;
            }
            0..=0x1f => return None,
            _ => i += 1,
        }
    }
    None
}

/// As bits, the bytes `b[i..i + 16]` that are `"`, `\` or a control character.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn special_mask(b: &[u8], i: usize) -> u32 {
    use std::arch::x86_64::*;
    assert!(i + 16 <= b.len());
    // SAFETY: SSE2 is part of x86_64; the load reads the 16 bytes from `i`, within `b`.
    unsafe {
        let v = _mm_loadu_si128(b.as_ptr().add(i).cast());
        let special = _mm_or_si128(
            _mm_or_si128(
                _mm_cmpeq_epi8(v, _mm_set1_epi8(b'"' as i8)),
                _mm_cmpeq_epi8(v, _mm_set1_epi8(b'\\' as i8)),
            ),
            // v <= 0x1f, unsigned
            _mm_cmpeq_epi8(_mm_min_epu8(v, _mm_set1_epi8(0x1f)), v),
        );
        _mm_movemask_epi8(special) as u32
    }
}

/// The index of the first byte from `i` on that ends a plain run of a JSON string: `"`, `\` or a
/// control character (or the length).
#[inline(always)]
fn find_special(b: &[u8], mut i: usize) -> usize {
    #[cfg(target_arch = "x86_64")]
    while i + 16 <= b.len() {
        let mask = special_mask(b, i);
        if mask != 0 {
            return i + mask.trailing_zeros() as usize;
        }
        i += 16;
    }
    while i < b.len() && !matches!(b[i], b'"' | b'\\' | 0..=0x1f) {
        i += 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simd_searches_agree_with_byte_loops() {
        let mut text = Vec::new();
        for k in 0..600u32 {
            text.push(match k.wrapping_mul(2_654_435_761) >> 27 {
                0 => b'"',
                1 => b'\\',
                2 => 0x1f,
                3 => b'\n',
                4 => b'\t',
                5 => b'\r',
                6 => 0x7f,
                7 => 0xc3,
                8..=20 => b' ',
                _ => b'a',
            });
        }
        for i in 0..=text.len() {
            let special = (i..text.len())
                .find(|&k| matches!(text[k], b'"' | b'\\' | 0..=0x1f))
                .unwrap_or(text.len());
            assert_eq!(find_special(&text, i), special, "from {i}");
            let other = (i..text.len())
                .find(|&k| !is_ws(text[k]))
                .unwrap_or(text.len());
            assert_eq!(skip_ws(&text, i), other, "from {i}");
        }
    }
}
