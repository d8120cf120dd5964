//! The reader under the registry: quick-xml events over the text in memory, located errors, attributes,
//! the `<registry>` sections dispatched to their readers, and the interned attribute names.

use super::*;
use crate::error::line_col;
use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use std::borrow::Cow;

pub(super) enum Ev<'a> {
    Open(BytesStart<'a>, bool),
    Close,
    Text(quick_xml::events::BytesText<'a>),
}

pub(super) struct Parser<'a> {
    pub(super) src: &'a str,
    pub(super) origin: &'a str,
    pub(super) r: Reader<&'a [u8]>,
    pub(super) reg: Registry,
    /// enum value name -> (group, index), maintained while parsing for de-duplication
    pub(super) values: FastMap<String, (usize, usize)>,
    pub(super) groups: FastMap<String, usize>,
    pub(super) pending_ext: Vec<(String, PendingValue)>,
}

/// A value added by a feature or extension, applied once all `<enums>` are read.
pub(super) struct PendingValue {
    pub(super) value: EnumValue,
    pub(super) offset_pos: usize,
}

pub(super) fn is_vulkan_api(api: Option<&str>) -> bool {
    api.unwrap_or("vulkan")
        .split(',')
        .any(|x| x.trim() == "vulkan")
}

pub(super) fn split_list(s: &str) -> Vec<String> {
    s.split(',')
        .map(|x| x.trim())
        .filter(|x| !x.is_empty())
        .map(String::from)
        .collect()
}

/// Parse an integer literal as used in vk.xml (`0x10`, `-1`, `(~0U)`, `(~0ULL)`, `1000U`).
pub fn parse_int_literal(s: &str) -> Option<i64> {
    let t = s
        .trim()
        .trim_start_matches('(')
        .trim_end_matches(')')
        .trim();
    let (neg_bits, body) = match t.strip_prefix('~') {
        Some(b) => (true, b),
        None => (false, t),
    };
    let wide = body.ends_with("ULL") || body.ends_with("LL");
    let num = body.trim_end_matches(['U', 'L', 'u', 'l']);
    let (neg, num) = match num.strip_prefix('-') {
        Some(n) => (true, n),
        None => (false, num),
    };
    let v: i64 = if let Some(h) = num.strip_prefix("0x").or_else(|| num.strip_prefix("0X")) {
        i64::from_str_radix(h, 16).ok()?
    } else {
        num.parse::<i64>().ok()?
    };
    let v = if neg { v.checked_neg()? } else { v };
    if neg_bits {
        if wide {
            Some(!v)
        } else {
            Some((!(v as u32)) as i64)
        }
    } else {
        Some(v)
    }
}

pub(super) fn collapse(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for w in s.split_whitespace() {
        if !out.is_empty() {
            out.push(' ');
        }
        out.push_str(w);
    }
    out
}

pub(super) fn intern(k: &[u8]) -> &'static str {
    macro_rules! keys {
        ($($s:literal),*) => {
            match k {
                $( x if x == $s.as_bytes() => $s, )*
                _ => "",
            }
        };
    }
    keys!(
        "name",
        "category",
        "alias",
        "api",
        "parent",
        "objtypeenum",
        "requires",
        "bitvalues",
        "structextends",
        "returnedonly",
        "allowduplicate",
        "deprecated",
        "optional",
        "len",
        "altlen",
        "values",
        "noautovalidity",
        "limittype",
        "selector",
        "selection",
        "externsync",
        "objecttype",
        "stride",
        "validstructs",
        "successcodes",
        "errorcodes",
        "queues",
        "renderpass",
        "videocoding",
        "cmdbufferlevel",
        "tasks",
        "type",
        "bitwidth",
        "value",
        "bitpos",
        "offset",
        "extnumber",
        "dir",
        "extends",
        "protect",
        "number",
        "depends",
        "comment",
        "extension",
        "feature",
        "supported",
        "promotedto",
        "deprecatedby",
        "obsoletedby",
        "platform",
        "provisional",
        "specialuse",
        "ratified",
        "author",
        "contact",
        "struct"
    )
}

impl<'a> Parser<'a> {
    pub(super) fn new(src: &'a str, origin: &'a str) -> Self {
        let mut r = Reader::from_str(src);
        r.config_mut().trim_text(false);
        Parser {
            src,
            origin,
            r,
            reg: Registry::default(),
            values: FastMap::default(),
            groups: FastMap::default(),
            pending_ext: Vec::new(),
        }
    }

    pub(super) fn err_at(&self, pos: usize, msg: impl Into<String>) -> RegistryError {
        let (line, column) = line_col(self.src, pos);
        RegistryError::at_line_col(self.origin, line, column, msg)
    }

    pub(super) fn err_here(&self, msg: impl Into<String>) -> RegistryError {
        self.err_at(self.r.buffer_position() as usize, msg)
    }

    pub(super) fn xml_err(&self, e: quick_xml::Error) -> RegistryError {
        self.err_at(
            self.r.error_position() as usize,
            format!("malformed XML: {e}"),
        )
    }

    pub(super) fn next(&mut self) -> Result<Option<Ev<'a>>, RegistryError> {
        loop {
            let ev = self.r.read_event().map_err(|e| self.xml_err(e))?;
            return Ok(Some(match ev {
                Event::Start(e) => Ev::Open(e, false),
                Event::Empty(e) => Ev::Open(e, true),
                Event::End(_) => Ev::Close,
                Event::Text(t) => Ev::Text(t),
                Event::CData(t) => Ev::Text(quick_xml::events::BytesText::from_escaped(
                    String::from_utf8_lossy(&t).into_owned(),
                )),
                Event::Comment(_) | Event::Decl(_) | Event::PI(_) | Event::DocType(_) => continue,
                Event::Eof => return Ok(None),
            }));
        }
    }

    /// The next event inside `ctx`; end of file is an error.
    pub(super) fn child(&mut self, ctx: &str) -> Result<Ev<'a>, RegistryError> {
        match self.next()? {
            Some(ev) => Ok(ev),
            None => Err(self.err_here(format!("unexpected end of file inside <{ctx}>"))),
        }
    }

    pub(super) fn skip(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        if !empty {
            let name = e.name();
            self.r.read_to_end(name).map_err(|err| match err {
                quick_xml::Error::Syntax(_) | quick_xml::Error::IllFormed(_)
                    if self.r.buffer_position() as usize >= self.src.len() =>
                {
                    self.err_here(format!(
                        "unexpected end of file inside <{}>",
                        String::from_utf8_lossy(name.as_ref())
                    ))
                }
                other => self.xml_err(other),
            })?;
        }
        Ok(())
    }

    pub(super) fn unescape<'t>(
        &self,
        t: &'t quick_xml::events::BytesText<'a>,
    ) -> Result<Cow<'t, str>, RegistryError> {
        t.unescape().map_err(|e| self.xml_err(e))
    }

    pub(super) fn start_pos(&self) -> usize {
        // buffer_position is just after the tag; find its '<' for error locations
        let p = (self.r.buffer_position() as usize).min(self.src.len());
        self.src[..p].rfind('<').unwrap_or(0)
    }

    pub(super) fn unexpected(&self, e: &BytesStart, ctx: &str) -> RegistryError {
        self.err_at(
            self.start_pos(),
            format!(
                "unexpected element <{}> inside <{ctx}>",
                String::from_utf8_lossy(e.name().as_ref())
            ),
        )
    }

    pub(super) fn attrs<'e>(
        &self,
        e: &'e BytesStart<'a>,
    ) -> Result<Vec<(&'static str, Cow<'e, str>)>, RegistryError> {
        // keys are interned against a fixed list to keep matching cheap
        let mut out = Vec::new();
        for a in e.attributes().with_checks(false) {
            let a = a.map_err(|err| {
                self.err_at(self.start_pos(), format!("malformed attribute: {err}"))
            })?;
            let key = intern(a.key.as_ref());
            if key.is_empty() {
                continue;
            }
            let val: Cow<'e, str> = match a.value {
                Cow::Borrowed(bytes) => {
                    let raw = std::str::from_utf8(bytes)
                        .map_err(|_| self.err_at(self.start_pos(), "attribute is not UTF-8"))?;
                    if raw.contains('&') {
                        Cow::Owned(
                            quick_xml::escape::unescape(raw)
                                .map_err(|err| {
                                    self.err_at(
                                        self.start_pos(),
                                        format!("bad escape in attribute: {err}"),
                                    )
                                })?
                                .into_owned(),
                        )
                    } else {
                        Cow::Borrowed(raw)
                    }
                }
                Cow::Owned(bytes) => {
                    let raw = String::from_utf8(bytes)
                        .map_err(|_| self.err_at(self.start_pos(), "attribute is not UTF-8"))?;
                    Cow::Owned(
                        quick_xml::escape::unescape(&raw)
                            .map_err(|err| {
                                self.err_at(
                                    self.start_pos(),
                                    format!("bad escape in attribute: {err}"),
                                )
                            })?
                            .into_owned(),
                    )
                }
            };
            out.push((key, val));
        }
        Ok(out)
    }

    pub(super) fn run(mut self) -> Result<Registry, RegistryError> {
        // find <registry>
        loop {
            match self.next()? {
                None => return Err(self.err_here("no <registry> element")),
                Some(Ev::Open(e, empty)) if e.name().as_ref() == b"registry" => {
                    if !empty {
                        self.registry()?;
                    }
                    break;
                }
                Some(Ev::Open(e, _)) => return Err(self.unexpected(&e, "document")),
                Some(Ev::Close) => return Err(self.err_here("unexpected closing tag")),
                Some(Ev::Text(_)) => {}
            }
        }
        while let Some(ev) = self.next()? {
            match ev {
                Ev::Text(t) if t.iter().all(|b| b.is_ascii_whitespace()) => {}
                _ => return Err(self.err_here("content after </registry>")),
            }
        }
        self.apply_pending()?;
        self.resolve_aliases();
        let mut reg = self.reg;
        reg.build_index(self.values, self.groups);
        Ok(reg)
    }

    pub(super) fn registry(&mut self) -> Result<(), RegistryError> {
        loop {
            match self.child("registry")? {
                Ev::Close => return Ok(()),
                Ev::Text(_) => {}
                Ev::Open(e, empty) => match e.name().as_ref() {
                    b"types" => self.container(&e, empty, "types")?,
                    b"enums" => self.enums(&e, empty)?,
                    b"commands" => self.container(&e, empty, "commands")?,
                    b"feature" => self.feature(&e, empty)?,
                    b"extensions" => self.container(&e, empty, "extensions")?,
                    b"comment" | b"platforms" | b"tags" | b"formats" | b"spirvextensions"
                    | b"spirvcapabilities" | b"sync" | b"videocodecs" => self.skip(&e, empty)?,
                    _ => return Err(self.unexpected(&e, "registry")),
                },
            }
        }
    }

    pub(super) fn container(
        &mut self,
        _e: &BytesStart<'a>,
        empty: bool,
        ctx: &'static str,
    ) -> Result<(), RegistryError> {
        if empty {
            return Ok(());
        }
        loop {
            match self.child(ctx)? {
                Ev::Close => return Ok(()),
                Ev::Text(_) => {}
                Ev::Open(e, empty) => match (ctx, e.name().as_ref()) {
                    (_, b"comment") => self.skip(&e, empty)?,
                    ("types", b"type") => self.type_def(&e, empty)?,
                    ("commands", b"command") => self.command(&e, empty)?,
                    ("extensions", b"extension") => self.extension(&e, empty)?,
                    _ => return Err(self.unexpected(&e, ctx)),
                },
            }
        }
    }
}
