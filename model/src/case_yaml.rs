//! A case's YAML written straight from its serde form: byte for byte what the slow path writes
//! (serde_yaml's block output rewritten by [`crate::compact`]) at a fraction of its cost, or nothing
//! when the case holds something whose text this writer does not know for certain (a string that
//! needs quotes, a multi-line text, a character); the slow path then writes that case.
//!
//! Two steps: a [`serde::Serializer`] that records the value as a flat list of events (each scalar
//! already as the text serde_yaml prints, each collection with its extent and whether `compact`
//! writes it as a flow collection), then a writer that lays the events out as serde_yaml's emitter
//! does, with `compact`'s flow sequences and flow mappings decided from the structure instead of
//! read back from the lines.

use crate::Case;
use serde::ser::{self, Serialize};
use std::borrow::Cow;
use std::fmt::Write as _;

/// The case's YAML, as [`Case::to_yaml`] writes it: the fast writer's, or the slow path's when the
/// fast writer gives up.
pub fn write(case: &Case) -> String {
    fast(case).unwrap_or_else(|_| slow(case))
}

/// The slow path, and the reference the fast writer is held to: serde_yaml's block output with
/// [`crate::compact`]'s flow collections.
pub fn slow<T: ?Sized + Serialize>(value: &T) -> String {
    crate::compact::compact_yaml(&serde_yaml::to_string(value).expect("a case always serialises"))
}

/// `value`'s YAML as [`slow`] writes it, byte for byte; an error when `value` holds something this
/// writer is not certain serde_yaml writes as it would (the error says what), or is not a mapping.
pub fn fast<T: ?Sized + Serialize>(value: &T) -> Result<String, GaveUp> {
    let events = Events::of(value)?;
    let mut w = Writer {
        events: &events.list,
        text: &events.text,
        out: String::with_capacity(2 * events.text.len() + 4 * events.list.len()),
    };
    match events.list.first() {
        Some(&Event::Open {
            kind: Kind::Map,
            tag: None,
            len,
            ..
        }) if len > 0 => w.mapping(0, 0, false)?,
        _ => return Err(GaveUp::at("a document that is not a non-empty mapping")),
    }
    Ok(w.out)
}

/// What made the fast writer give up on a value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GaveUp(Cow<'static, str>);

impl GaveUp {
    fn at(what: &'static str) -> GaveUp {
        GaveUp(Cow::Borrowed(what))
    }
}

impl std::fmt::Display for GaveUp {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "the fast YAML writer gave up: {}", self.0)
    }
}

impl std::error::Error for GaveUp {}

impl ser::Error for GaveUp {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        GaveUp(Cow::Owned(msg.to_string()))
    }
}

/// A byte that may stand in a string written plain here.
const PLAIN: u8 = 1;
/// A byte that may stand in a word of [`crate::compact`] (after its first).
const WORD: u8 = 2;
/// A byte that may stand in a decimal integer or float.
const DECIMAL: u8 = 4;

/// Each byte's classes.
const CLASSES: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut c = 0;
    while c < 256 {
        let b = c as u8;
        t[c] = match b {
            b'0'..=b'9' => PLAIN | WORD | DECIMAL,
            b'e' | b'E' | b'.' | b'+' | b'-' => PLAIN | WORD | DECIMAL,
            b'a'..=b'z' | b'A'..=b'Z' | b'_' => PLAIN | WORD,
            b'/' | b' ' => PLAIN,
            _ => 0,
        };
        c += 1;
    }
    t
};

/// Whether serde_yaml certainly writes the string `s` as it is, a plain scalar on one line, in a
/// block mapping or sequence: ASCII letters, digits, `_ . + - /` and single inner spaces, starting
/// with a letter, a digit or `_`, and not read back as anything but a string (null, a boolean, an
/// integer, a float). Then whether it is a word of [`crate::compact`] (it is never a number there:
/// one that could be is not plain). None for other strings: many are plain too, but they are left
/// to the slow path.
fn plain_word(s: &str) -> Option<bool> {
    let b = s.as_bytes();
    let (&first, &last) = (b.first()?, b.last()?);
    if !(first.is_ascii_alphanumeric() || first == b'_') || last == b' ' {
        return None;
    }
    let mut all = PLAIN | WORD | DECIMAL;
    let mut after_space = false;
    for &c in b {
        let class = CLASSES[c as usize];
        let space = c == b' ';
        if class & PLAIN == 0 || (space && after_space) {
            return None;
        }
        after_space = space;
        all &= class;
    }
    if quoted_keyword(s) {
        return None;
    }
    // A text that starts with a digit reads as a string only when it cannot be an integer or a
    // float: no radix prefix, and a byte no decimal number holds.
    if first.is_ascii_digit()
        && (all & DECIMAL != 0 || (first == b'0' && matches!(b.get(1), Some(b'x' | b'o' | b'b'))))
    {
        return None;
    }
    Some(all & WORD != 0)
}

/// Whether `s` is a word serde_yaml reads as null or a boolean, so writes single-quoted when it is a
/// string (`'null'`, `'true'`).
fn quoted_keyword(s: &str) -> bool {
    matches!(
        s,
        "null" | "Null" | "NULL" | "true" | "True" | "TRUE" | "false" | "False" | "FALSE"
    )
}

/// Whether `variant` is written as the tag `!variant` with nothing escaped.
fn plain_tag(variant: &str) -> bool {
    !variant.is_empty()
        && variant
            .bytes()
            .all(|c| c.is_ascii_alphanumeric() || c == b'-' || c == b'_')
}

/// Appends `v` as serde_yaml writes a float: `.inf`, `-.inf`, `.nan`, or the `ryu` crate's
/// shortest text (serde_yaml's own formatter).
fn push_float(out: &mut String, v: impl ryu::Float + Into<f64>) {
    let wide: f64 = v.into();
    if wide.is_nan() {
        out.push_str(".nan");
    } else if wide.is_infinite() {
        out.push_str(if wide > 0.0 { ".inf" } else { "-.inf" });
    } else {
        out.push_str(ryu::Buffer::new().format_finite(v));
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Seq,
    Map,
}

/// One node of the value, in serialisation order: a collection's children follow it (a mapping's
/// as key, value, key, value...).
#[derive(Debug, Clone, Copy)]
enum Event {
    /// A scalar, its text `Events::text[start..end]` as serde_yaml prints it.
    Scalar {
        start: u32,
        end: u32,
        /// The enum variant it is the value of (`!group 0`).
        tag: Option<&'static str>,
    },
    Open {
        kind: Kind,
        tag: Option<&'static str>,
        /// The index of the first event after its last descendant.
        end: u32,
        /// Its items, or its entries.
        len: u32,
        /// Untagged, not empty, and written by `compact` as one flow collection where it can be: a
        /// sequence of words, or a mapping of words (not numbers) to words and flow sequences.
        flow: bool,
    },
}

/// A collection being recorded.
struct Frame {
    at: usize,
    kind: Kind,
    children: u32,
    flow: bool,
}

/// What a finished child tells the collection it stands in.
#[derive(Clone, Copy)]
struct Finished {
    /// An untagged scalar that is a word.
    word: bool,
    /// An untagged non-empty sequence of words.
    flow_sequence: bool,
    /// As a key: None when it cannot be one here; else whether it is a word and not a number.
    key: Option<bool>,
}

/// The serializer: the value's events, and the text of its scalars.
struct Events {
    list: Vec<Event>,
    text: String,
    open: Vec<Frame>,
    /// The variant whose value the next node is (serde_yaml's tag).
    tag: Option<&'static str>,
}

/// The longest key written here: serde_yaml writes a key longer than 128 characters as a complex key
/// (`? key`).
const LONGEST_KEY: usize = 100;

impl Events {
    fn of<T: ?Sized + Serialize>(value: &T) -> Result<Events, GaveUp> {
        let mut events = Events {
            list: Vec::with_capacity(512),
            text: String::with_capacity(4096),
            open: Vec::with_capacity(16),
            tag: None,
        };
        value.serialize(&mut events)?;
        if !events.open.is_empty() || events.tag.is_some() {
            return Err(GaveUp::at("an unfinished value"));
        }
        Ok(events)
    }

    fn finished(&mut self, f: Finished) -> Result<(), GaveUp> {
        let Some(frame) = self.open.last_mut() else {
            return Ok(());
        };
        match frame.kind {
            Kind::Seq => frame.flow &= f.word,
            Kind::Map if frame.children % 2 == 0 => {
                let word = f.key.ok_or(GaveUp::at(
                    "a key that is not a short string or a non-negative integer",
                ))?;
                frame.flow &= word;
            }
            Kind::Map => frame.flow &= f.word || f.flow_sequence,
        }
        frame.children += 1;
        Ok(())
    }

    /// A scalar whose text `put` appends: a `word` of `compact` when untagged, and as a key, None
    /// when it cannot be one here, else whether `compact` puts it in a flow mapping (a word, not a
    /// number).
    fn scalar(
        &mut self,
        put: impl FnOnce(&mut String),
        word: bool,
        key: Option<bool>,
    ) -> Result<(), GaveUp> {
        let start = self.text.len();
        put(&mut self.text);
        let (Ok(start), Ok(end)) = (u32::try_from(start), u32::try_from(self.text.len())) else {
            return Err(GaveUp::at("a value of more than 4 GiB of text"));
        };
        let tag = self.tag.take();
        let untagged = tag.is_none();
        self.list.push(Event::Scalar { start, end, tag });
        self.finished(Finished {
            word: word && untagged,
            flow_sequence: false,
            key: key.filter(|_| untagged),
        })
    }

    fn string(&mut self, s: &str) -> Result<(), GaveUp> {
        if quoted_keyword(s) {
            // Never a key here: `compact` reads a quoted key's line otherwise.
            return self.scalar(
                |t| {
                    t.push('\'');
                    t.push_str(s);
                    t.push('\'');
                },
                false,
                None,
            );
        }
        let Some(word) = plain_word(s) else {
            return Err(GaveUp(Cow::Owned(format!(
                "the string {s:?} may need quotes or lines of its own"
            ))));
        };
        self.scalar(
            |t| t.push_str(s),
            word,
            (s.len() <= LONGEST_KEY).then_some(word),
        )
    }

    /// An integer: a word and a number to `compact` (a mapping keyed by one stays a block mapping).
    /// A negative one is no key here: `compact` reads a key that starts with `-` as a sequence item
    /// when it follows a sequence of words.
    fn integer(&mut self, negative: bool, magnitude: u64) -> Result<(), GaveUp> {
        self.scalar(
            |t| {
                let mut digits = [0u8; 21];
                let mut at = digits.len();
                let mut rest = magnitude;
                loop {
                    at -= 1;
                    digits[at] = b'0' + (rest % 10) as u8;
                    rest /= 10;
                    if rest == 0 {
                        break;
                    }
                }
                if negative {
                    at -= 1;
                    digits[at] = b'-';
                }
                t.push_str(std::str::from_utf8(&digits[at..]).unwrap_or_default());
            },
            true,
            (!negative).then_some(false),
        )
    }

    /// A 128-bit integer, as [`Events::integer`].
    fn wide_integer(&mut self, v: impl std::fmt::Display, negative: bool) -> Result<(), GaveUp> {
        self.scalar(
            |t| {
                let _ = write!(t, "{v}");
            },
            true,
            (!negative).then_some(false),
        )
    }

    fn open(&mut self, kind: Kind) -> Result<(), GaveUp> {
        let tag = self.tag.take();
        self.open.push(Frame {
            at: self.list.len(),
            kind,
            children: 0,
            flow: tag.is_none(),
        });
        self.list.push(Event::Open {
            kind,
            tag,
            end: 0,
            len: 0,
            flow: false,
        });
        Ok(())
    }

    fn close(&mut self) -> Result<(), GaveUp> {
        let frame = self
            .open
            .pop()
            .ok_or(GaveUp::at("a collection closed twice"))?;
        let len = match frame.kind {
            Kind::Seq => frame.children,
            Kind::Map if frame.children % 2 == 0 => frame.children / 2,
            Kind::Map => return Err(GaveUp::at("a key without a value")),
        };
        let flow = frame.flow && len > 0;
        let end = u32::try_from(self.list.len())
            .map_err(|_| GaveUp::at("a value of more than 4 billion nodes"))?;
        if let Event::Open {
            end: e,
            len: l,
            flow: f,
            ..
        } = &mut self.list[frame.at]
        {
            (*e, *l, *f) = (end, len, flow);
        }
        self.finished(Finished {
            word: false,
            flow_sequence: frame.kind == Kind::Seq && flow,
            key: None,
        })
    }

    /// The next node is the value of `variant`.
    fn variant(&mut self, variant: &'static str) -> Result<(), GaveUp> {
        if self.tag.is_some() {
            return Err(GaveUp::at("a variant inside a variant"));
        }
        if !plain_tag(variant) {
            return Err(GaveUp::at("a variant name that is not a plain tag"));
        }
        self.tag = Some(variant);
        Ok(())
    }
}

impl ser::Serializer for &mut Events {
    type Ok = ();
    type Error = GaveUp;
    type SerializeSeq = Self;
    type SerializeTuple = Self;
    type SerializeTupleStruct = Self;
    type SerializeTupleVariant = Self;
    type SerializeMap = Self;
    type SerializeStruct = Self;
    type SerializeStructVariant = Self;

    fn serialize_bool(self, v: bool) -> Result<(), GaveUp> {
        self.scalar(|t| t.push_str(if v { "true" } else { "false" }), true, None)
    }
    fn serialize_i8(self, v: i8) -> Result<(), GaveUp> {
        self.serialize_i64(v.into())
    }
    fn serialize_i16(self, v: i16) -> Result<(), GaveUp> {
        self.serialize_i64(v.into())
    }
    fn serialize_i32(self, v: i32) -> Result<(), GaveUp> {
        self.serialize_i64(v.into())
    }
    fn serialize_i64(self, v: i64) -> Result<(), GaveUp> {
        self.integer(v < 0, v.unsigned_abs())
    }
    fn serialize_i128(self, v: i128) -> Result<(), GaveUp> {
        self.wide_integer(v, v < 0)
    }
    fn serialize_u8(self, v: u8) -> Result<(), GaveUp> {
        self.integer(false, v.into())
    }
    fn serialize_u16(self, v: u16) -> Result<(), GaveUp> {
        self.integer(false, v.into())
    }
    fn serialize_u32(self, v: u32) -> Result<(), GaveUp> {
        self.integer(false, v.into())
    }
    fn serialize_u64(self, v: u64) -> Result<(), GaveUp> {
        self.integer(false, v)
    }
    fn serialize_u128(self, v: u128) -> Result<(), GaveUp> {
        self.wide_integer(v, false)
    }
    fn serialize_f32(self, v: f32) -> Result<(), GaveUp> {
        // Every text it writes is a number to `compact`: a word, never a key here.
        self.scalar(|t| push_float(t, v), true, None)
    }
    fn serialize_f64(self, v: f64) -> Result<(), GaveUp> {
        self.scalar(|t| push_float(t, v), true, None)
    }
    fn serialize_char(self, _: char) -> Result<(), GaveUp> {
        Err(GaveUp::at("a character (written quoted)"))
    }
    fn serialize_str(self, v: &str) -> Result<(), GaveUp> {
        self.string(v)
    }
    fn serialize_bytes(self, _: &[u8]) -> Result<(), GaveUp> {
        Err(GaveUp::at("bytes (serde_yaml refuses them)"))
    }
    fn serialize_none(self) -> Result<(), GaveUp> {
        self.serialize_unit()
    }
    fn serialize_some<T: ?Sized + Serialize>(self, value: &T) -> Result<(), GaveUp> {
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<(), GaveUp> {
        self.scalar(|t| t.push_str("null"), true, None)
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<(), GaveUp> {
        self.serialize_unit()
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
    ) -> Result<(), GaveUp> {
        self.string(variant)
    }
    fn serialize_newtype_struct<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        value: &T,
    ) -> Result<(), GaveUp> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        value: &T,
    ) -> Result<(), GaveUp> {
        self.variant(variant)?;
        value.serialize(&mut *self)?;
        // A value that wrote no node would leave the tag to the next one.
        match self.tag {
            None => Ok(()),
            Some(_) => Err(GaveUp::at("a variant without a value")),
        }
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<Self, GaveUp> {
        self.open(Kind::Seq)?;
        Ok(self)
    }
    fn serialize_tuple(self, _: usize) -> Result<Self, GaveUp> {
        self.serialize_seq(None)
    }
    fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Self, GaveUp> {
        self.serialize_seq(None)
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Self, GaveUp> {
        self.variant(variant)?;
        self.serialize_seq(None)
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Self, GaveUp> {
        self.open(Kind::Map)?;
        Ok(self)
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Self, GaveUp> {
        self.serialize_map(None)
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Self, GaveUp> {
        self.variant(variant)?;
        self.serialize_map(None)
    }
    fn is_human_readable(&self) -> bool {
        true
    }
}

/// The compound serializers whose items carry no key: each serialised in turn, the collection
/// closed at its end.
macro_rules! unkeyed {
    ($($compound:ident :: $item:ident),*) => {$(
        impl ser::$compound for &mut Events {
            type Ok = ();
            type Error = GaveUp;
            fn $item<T: ?Sized + Serialize>(&mut self, v: &T) -> Result<(), GaveUp> {
                v.serialize(&mut **self)
            }
            fn end(self) -> Result<(), GaveUp> {
                self.close()
            }
        }
    )*};
}

unkeyed!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

/// The struct serializers: each field its name's key, then its value.
macro_rules! fields {
    ($($compound:ident),*) => {$(
        impl ser::$compound for &mut Events {
            type Ok = ();
            type Error = GaveUp;
            fn serialize_field<T: ?Sized + Serialize>(
                &mut self,
                key: &'static str,
                v: &T,
            ) -> Result<(), GaveUp> {
                self.string(key)?;
                v.serialize(&mut **self)
            }
            fn end(self) -> Result<(), GaveUp> {
                self.close()
            }
        }
    )*};
}

fields!(SerializeStruct, SerializeStructVariant);

impl ser::SerializeMap for &mut Events {
    type Ok = ();
    type Error = GaveUp;
    fn serialize_key<T: ?Sized + Serialize>(&mut self, k: &T) -> Result<(), GaveUp> {
        k.serialize(&mut **self)
    }
    fn serialize_value<T: ?Sized + Serialize>(&mut self, v: &T) -> Result<(), GaveUp> {
        v.serialize(&mut **self)
    }
    fn end(self) -> Result<(), GaveUp> {
        self.close()
    }
}

/// Lays the events out as serde_yaml's block emitter does (two columns of indentation; a sequence
/// that is a mapping's value at its key's column; a sequence item's mapping starting on the item's
/// line, a tagged one on the next), with `compact`'s flow collections: a sequence of words that is
/// a mapping's value or a sequence's item as `[a, b]`, and a sequence item that maps words to words
/// and flow sequences as `{k: v, ...}`.
struct Writer<'a> {
    events: &'a [Event],
    text: &'a str,
    out: String,
}

impl<'a> Writer<'a> {
    /// The index of the event after node `i` and its descendants.
    fn after(&self, i: usize) -> usize {
        match self.events[i] {
            Event::Scalar { .. } => i + 1,
            Event::Open { end, .. } => end as usize,
        }
    }

    /// `column` spaces.
    fn indent(&mut self, column: usize) {
        const SPACES: &str = "                                ";
        let mut left = column;
        while left > 0 {
            let n = left.min(SPACES.len());
            self.out.push_str(&SPACES[..n]);
            left -= n;
        }
    }

    /// The text of scalar `i`.
    fn scalar_text(&self, i: usize) -> &'a str {
        match self.events[i] {
            Event::Scalar { start, end, .. } => &self.text[start as usize..end as usize],
            Event::Open { .. } => "",
        }
    }

    /// ` !tag` for a node's tag, when it has one.
    fn tag(&mut self, tag: Option<&str>) {
        if let Some(t) = tag {
            self.out.push_str(" !");
            self.out.push_str(t);
        }
    }

    /// The rest of a line that ends in a one-line node `i` (` value`, ` !tag value`, ` []`, ` {}`,
    /// ` [a, b]`); false when node `i` takes lines of its own.
    fn one_line(&mut self, i: usize) -> bool {
        match self.events[i] {
            Event::Scalar { tag, .. } => {
                self.tag(tag);
                self.out.push(' ');
                let text = self.scalar_text(i);
                self.out.push_str(text);
            }
            Event::Open {
                kind, tag, len: 0, ..
            } => {
                self.tag(tag);
                self.out
                    .push_str(if kind == Kind::Seq { " []" } else { " {}" });
            }
            Event::Open {
                kind: Kind::Seq,
                flow: true,
                ..
            } => {
                self.out.push(' ');
                self.flow_sequence(i);
            }
            Event::Open { .. } => return false,
        }
        self.out.push('\n');
        true
    }

    /// `[a, b, c]` for the flow sequence `i`.
    fn flow_sequence(&mut self, i: usize) {
        self.out.push('[');
        for (n, c) in (i + 1..self.after(i)).enumerate() {
            if n > 0 {
                self.out.push_str(", ");
            }
            let word = self.scalar_text(c);
            self.out.push_str(word);
        }
        self.out.push(']');
    }

    /// The entries of mapping `i` at `column`, the first on the current line when `inline` (after a
    /// sequence item's `- `).
    fn mapping(&mut self, i: usize, column: usize, inline: bool) -> Result<(), GaveUp> {
        let end = self.after(i);
        let mut k = i + 1;
        let mut first = true;
        while k < end {
            if !(first && inline) {
                self.indent(column);
            }
            first = false;
            let v = k + 1;
            let key = self.scalar_text(k);
            self.out.push_str(key);
            self.out.push(':');
            if !self.one_line(v) {
                match self.events[v] {
                    Event::Open {
                        kind: Kind::Seq,
                        tag,
                        ..
                    } => {
                        self.tag(tag);
                        self.out.push('\n');
                        self.items(v, column)?;
                    }
                    Event::Open {
                        kind: Kind::Map,
                        tag,
                        ..
                    } => {
                        self.tag(tag);
                        self.out.push('\n');
                        self.mapping(v, column + 2, false)?;
                    }
                    Event::Scalar { .. } => {}
                }
            }
            k = self.after(v);
        }
        Ok(())
    }

    /// The items of sequence `i`, each `- ` at `column`.
    fn items(&mut self, i: usize, column: usize) -> Result<(), GaveUp> {
        let end = self.after(i);
        let mut c = i + 1;
        while c < end {
            self.indent(column);
            self.out.push('-');
            if !self.one_line(c) {
                match self.events[c] {
                    Event::Open {
                        kind: Kind::Map,
                        tag: None,
                        flow: true,
                        ..
                    } => self.flow_mapping(c),
                    Event::Open {
                        kind: Kind::Map,
                        tag: None,
                        ..
                    } => {
                        self.out.push(' ');
                        self.mapping(c, column + 2, true)?;
                    }
                    Event::Open {
                        kind: Kind::Map,
                        tag,
                        ..
                    } => {
                        self.tag(tag);
                        self.out.push('\n');
                        self.mapping(c, column + 2, false)?;
                    }
                    Event::Open {
                        kind: Kind::Seq,
                        tag: Some(tag),
                        ..
                    } => {
                        self.tag(Some(tag));
                        self.out.push('\n');
                        self.items(c, column + 2)?;
                    }
                    // A sequence of more than words inside a sequence: serde_yaml starts it on
                    // the item's line (`- - `), and `compact`, reading lines, treats its first
                    // item otherwise than the rest (a mapping there stays a block mapping).
                    _ => return Err(GaveUp::at("a sequence of more than words in a sequence")),
                }
            }
            c = self.after(c);
        }
        Ok(())
    }

    /// ` {k: v, k: [a, b]}` and the line's end for the flow mapping `i`.
    fn flow_mapping(&mut self, i: usize) {
        self.out.push_str(" {");
        let end = self.after(i);
        let mut k = i + 1;
        while k < end {
            if k > i + 1 {
                self.out.push_str(", ");
            }
            let key = self.scalar_text(k);
            self.out.push_str(key);
            self.out.push_str(": ");
            let v = k + 1;
            match self.events[v] {
                Event::Scalar { .. } => {
                    let value = self.scalar_text(v);
                    self.out.push_str(value);
                }
                Event::Open { .. } => self.flow_sequence(v),
            }
            k = self.after(v);
        }
        self.out.push_str("}\n");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::ser::{SerializeMap, SerializeStructVariant, SerializeTupleVariant};

    use crate::compact::{is_number, is_word};

    /// A small deterministic generator (xorshift64*).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
        fn pick<T: Copy>(&mut self, from: &[T]) -> T {
            from[self.below(from.len())]
        }
        /// Mostly round values, now and then any bit pattern (NaN, infinities, subnormals).
        fn f32(&mut self) -> f32 {
            match self.below(4) {
                0 => f32::from_bits(self.next() as u32),
                1 => self.pick(&[
                    0.0,
                    -0.0,
                    0.5,
                    -1000.0,
                    1e-7,
                    0.000_001,
                    1e15,
                    1e16,
                    2_097_152.2,
                    0.000_244_140_63,
                    123_456_790.0,
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    f32::NAN,
                    f32::MIN_POSITIVE,
                    f32::MAX,
                ]),
                2 => (self.below(2001) as f32 - 1000.0) / 8.0,
                _ => (self.below(2001) as f32 - 1000.0) * 0.01,
            }
        }
    }

    /// Strings serde_yaml writes plain, quoted or over several lines.
    const STRINGS: &[&str] = &[
        "raygen",
        "x",
        "VK_FORMAT_R32G32B32A32_UINT",
        "shader-read-only-optimal",
        "2d",
        "1/0",
        "a b",
        "x_y.z+w",
        "true",
        "False",
        "null",
        "~",
        "1.5",
        "1e5",
        "012",
        "0x1F",
        "",
        "a: b",
        "- x",
        "-x",
        "#c",
        "a #b",
        "!x",
        "x ",
        " x",
        "a\nb",
        "two\nlines\n",
        "é",
        "'q'",
        "[x",
        "x]",
        "a,b",
        "|",
        "x |",
        "inf",
        ".nan",
        "---",
    ];

    const VARIANTS: &[&str] = &["general", "2d", "a_b", "shader-records", "Up", "no tag"];
    const FIELDS: &[&str] = &["a", "b", "origin", "min", "x_y", "1", "a b", "null"];

    /// Any shape serde can hand a serializer, for holding the fast writer to the slow path on
    /// layouts no case has (yet).
    #[derive(Debug, Clone)]
    enum Tree {
        Str(&'static str),
        Int(i64),
        Float(f32),
        Bool(bool),
        Null,
        Char(char),
        Seq(Vec<Tree>),
        Map(Vec<(Tree, Tree)>),
        Unit(&'static str),
        Newtype(&'static str, Box<Tree>),
        Struct(&'static str, Vec<(&'static str, Tree)>),
        Tuple(&'static str, Vec<Tree>),
    }

    impl Serialize for Tree {
        fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            match self {
                Tree::Str(v) => s.serialize_str(v),
                Tree::Int(v) => s.serialize_i64(*v),
                Tree::Float(v) => s.serialize_f32(*v),
                Tree::Bool(v) => s.serialize_bool(*v),
                Tree::Null => s.serialize_none(),
                Tree::Char(v) => s.serialize_char(*v),
                Tree::Seq(v) => v.serialize(s),
                Tree::Map(entries) => {
                    let mut m = s.serialize_map(Some(entries.len()))?;
                    for (k, v) in entries {
                        m.serialize_entry(k, v)?;
                    }
                    m.end()
                }
                Tree::Unit(name) => s.serialize_unit_variant("T", 0, name),
                Tree::Newtype(name, v) => s.serialize_newtype_variant("T", 0, name, v),
                Tree::Struct(name, fields) => {
                    let mut m = s.serialize_struct_variant("T", 0, name, fields.len())?;
                    for (k, v) in fields {
                        m.serialize_field(k, v)?;
                    }
                    m.end()
                }
                Tree::Tuple(name, items) => {
                    let mut t = s.serialize_tuple_variant("T", 0, name, items.len())?;
                    for v in items {
                        t.serialize_field(v)?;
                    }
                    t.end()
                }
            }
        }
    }

    fn scalar(r: &mut Rng) -> Tree {
        match r.below(40) {
            0 => Tree::Str(r.pick(STRINGS)),
            1..=11 => Tree::Str(r.pick(&STRINGS[..8])),
            12..=23 => Tree::Float(r.f32()),
            24..=28 => Tree::Int(r.next() as i64 >> r.below(64)),
            29..=31 => Tree::Bool(r.below(2) == 0),
            32..=34 => Tree::Null,
            35..=38 => Tree::Unit(r.pick(VARIANTS)),
            _ if r.below(4) == 0 => Tree::Char('c'),
            _ => Tree::Str(r.pick(&STRINGS[..8])),
        }
    }

    fn tree(r: &mut Rng, depth: usize) -> Tree {
        if depth == 0 || r.below(3) == 0 {
            return scalar(r);
        }
        let n = r.below(4);
        let words = r.below(2) == 0;
        let child = |r: &mut Rng| match words {
            // Mostly words, so that the flow collections are exercised.
            true if r.below(6) > 0 => Tree::Float(r.f32()),
            _ => tree(r, depth - 1),
        };
        match r.below(7) {
            0 | 1 => Tree::Seq((0..n).map(|_| child(r)).collect()),
            2 | 3 => Tree::Map(
                (0..n)
                    .map(|_| {
                        let key = match r.below(8) {
                            0 => Tree::Int(r.below(10) as i64),
                            1 => scalar(r),
                            _ => Tree::Str(r.pick(FIELDS)),
                        };
                        (key, child(r))
                    })
                    .collect(),
            ),
            4 => Tree::Newtype(r.pick(VARIANTS), Box::new(child(r))),
            5 => Tree::Struct(
                r.pick(VARIANTS),
                (0..n).map(|_| (r.pick(FIELDS), child(r))).collect(),
            ),
            _ => Tree::Tuple(r.pick(VARIANTS), (0..n).map(|_| child(r)).collect()),
        }
    }

    /// Holds the serializer's flow flags (built from its own word and key flags, not from the text)
    /// to what `compact` reads in the text.
    fn flags_agree_with_the_text<T: Serialize>(value: &T) {
        let Ok(ev) = Events::of(value) else {
            return;
        };
        let text = |i: usize| match ev.list[i] {
            Event::Scalar { start, end, .. } => &ev.text[start as usize..end as usize],
            Event::Open { .. } => "",
        };
        let after = |i: usize| match ev.list[i] {
            Event::Scalar { .. } => i + 1,
            Event::Open { end, .. } => end as usize,
        };
        let children = |i: usize| {
            let mut out = Vec::new();
            let mut c = i + 1;
            while c < after(i) {
                out.push(c);
                c = after(c);
            }
            out
        };
        let word =
            |c: usize| matches!(ev.list[c], Event::Scalar { tag: None, .. }) && is_word(text(c));
        let words = |c: usize| {
            matches!(ev.list[c], Event::Open { kind: Kind::Seq, tag: None, len, .. } if len > 0)
                && children(c).into_iter().all(word)
        };
        for (i, e) in ev.list.iter().enumerate() {
            if let Event::Open {
                kind,
                tag,
                len,
                flow,
                ..
            } = *e
            {
                let kids = children(i);
                let expected = tag.is_none()
                    && len > 0
                    && match kind {
                        Kind::Seq => kids.iter().all(|&c| word(c)),
                        Kind::Map => kids.chunks(2).all(|kv| {
                            is_word(text(kv[0]))
                                && !is_number(text(kv[0]))
                                && (word(kv[1]) || words(kv[1]))
                        }),
                    };
                assert_eq!(flow, expected, "collection {i}");
            }
        }
    }

    /// The repository's case files that parse as cases.
    fn repository_cases() -> Vec<(String, Case)> {
        crate::test_cases::repository_case_files()
            .into_iter()
            .filter_map(|path| {
                let text = std::fs::read_to_string(&path).unwrap();
                let case = Case::from_yaml("c", &text).ok()?;
                Some((path.display().to_string(), case))
            })
            .collect()
    }

    #[test]
    fn every_repository_case_is_written_as_the_slow_path_writes_it() {
        let cases = repository_cases();
        assert!(cases.len() >= 20, "only {} case files read", cases.len());
        let mut gave_up = Vec::new();
        for (path, case) in &cases {
            flags_agree_with_the_text(case);
            let reference = slow(case);
            match fast(case) {
                Ok(text) => assert_eq!(text, reference, "{path}"),
                Err(e) => gave_up.push(format!("{path}: {e}")),
            }
            assert_eq!(case.to_yaml(), reference, "{path}");
        }
        assert!(
            gave_up.len() * 20 <= cases.len(),
            "the fast writer gave up on {} of {} cases: {gave_up:#?}",
            gave_up.len(),
            cases.len()
        );
    }

    /// The repository's cases with their floats drawn again (any bit pattern now and then), their
    /// names replaced by strings of every kind, and a seed.
    fn varied_cases(r: &mut Rng) -> Vec<Case> {
        fn vary(v: &mut serde_yaml::Value, r: &mut Rng, key: Option<&str>) {
            use serde_yaml::Value;
            match v {
                Value::Number(n) if n.is_f64() => *n = serde_yaml::Number::from(f64::from(r.f32())),
                Value::String(s) if key == Some("name") && r.below(40) == 0 => {
                    *s = r.pick(STRINGS).to_string();
                }
                Value::Sequence(items) => items.iter_mut().for_each(|i| vary(i, r, None)),
                Value::Mapping(m) => {
                    for (k, v) in m.iter_mut() {
                        vary(v, r, k.as_str());
                    }
                }
                Value::Tagged(t) => vary(&mut t.value, r, None),
                _ => {}
            }
        }
        let mut out = Vec::new();
        for (_, case) in repository_cases() {
            for _ in 0..3 {
                let mut value: serde_yaml::Value =
                    serde_yaml::from_str(&slow(&case)).expect("a case reads as a YAML value");
                vary(&mut value, r, None);
                if let Ok(mut c) = serde_yaml::from_value::<Case>(value) {
                    if r.below(2) == 0 {
                        c.seed = Some(format!("{}/{}", r.below(100), r.below(10)));
                    }
                    out.push(c);
                }
            }
        }
        out
    }

    #[test]
    fn varied_cases_are_written_as_the_slow_path_writes_them() {
        let mut r = Rng(0x9e37_79b9_7f4a_7c15);
        let cases = varied_cases(&mut r);
        assert!(cases.len() >= 60, "only {} varied cases", cases.len());
        let mut gave_up = 0;
        for case in &cases {
            let reference = slow(case);
            match fast(case) {
                Ok(text) => assert_eq!(text, reference),
                Err(_) => gave_up += 1,
            }
            assert_eq!(case.to_yaml(), reference);
        }
        // A name that needs quotes makes it give up; most names are plain.
        assert!(
            gave_up * 2 <= cases.len(),
            "the fast writer gave up on {gave_up} of {} varied cases",
            cases.len()
        );
    }

    #[test]
    fn any_shape_is_written_as_the_slow_path_writes_it_or_left_to_it() {
        let mut r = Rng(0x5851_f42d_4c95_7f2d);
        let (mut written, mut gave_up) = (0, 0);
        for _ in 0..20_000 {
            let top = Tree::Map(
                (0..1 + r.below(4))
                    .map(|_| (Tree::Str(r.pick(FIELDS)), tree(&mut r, 4)))
                    .collect(),
            );
            flags_agree_with_the_text(&top);
            match fast(&top) {
                Ok(text) => {
                    assert_eq!(text, slow(&top), "{top:?}");
                    written += 1;
                }
                Err(_) => gave_up += 1,
            }
        }
        // Trees of quoted strings, characters and nested variants are left to the slow path; the
        // rest must not be.
        assert!(written >= 5_000, "written {written}, gave up on {gave_up}");
    }

    #[test]
    fn strings_that_need_quotes_are_written_as_the_slow_path_writes_them() {
        let mut case = crate::test_cases::hand_case();
        for s in STRINGS {
            for field in 0..3 {
                let mut c = case.clone();
                match field {
                    0 => c.name = s.to_string(),
                    1 => c.profile = s.to_string(),
                    _ => c.seed = Some(s.to_string()),
                }
                let reference = slow(&c);
                if let Ok(text) = fast(&c) {
                    assert_eq!(text, reference, "{s:?}");
                }
                assert_eq!(c.to_yaml(), reference, "{s:?}");
            }
        }
        // A quoted or multi-line name is left to the slow path.
        for s in ["1.5", "a: b", "- x", "", "#c", "two\nlines\n", "é"] {
            case.name = s.to_string();
            assert!(fast(&case).is_err(), "{s:?}");
            assert_eq!(write(&case), slow(&case), "{s:?}");
        }
        for s in ["a-plain_name.1", "true", "null", "1/0"] {
            case.name = s.to_string();
            assert_eq!(fast(&case), Ok(slow(&case)), "{s:?}");
        }
    }

    #[test]
    fn what_is_written_reads_back_as_the_same_case() {
        for (path, case) in repository_cases() {
            let text = write(&case);
            let back = Case::from_yaml("back", &text).unwrap_or_else(|e| panic!("{path}: {e}"));
            // NaN is not equal to itself: the cases are compared through their slow-path text.
            assert_eq!(slow(&back), slow(&case), "{path}");
        }
    }

    #[test]
    fn plain_strings_are_what_serde_yaml_writes_plain() {
        let mut r = Rng(7);
        let alphabet = b"ab0e1x ./+-_:#'E";
        let mut texts: Vec<String> = STRINGS.iter().map(|s| s.to_string()).collect();
        for _ in 0..20_000 {
            let len = 1 + r.below(6);
            texts.push((0..len).map(|_| r.pick(alphabet) as char).collect());
        }
        let mut plain = 0;
        for s in &texts {
            if let Some(word) = plain_word(s) {
                assert_eq!(word, is_word(s), "{s:?}");
                assert!(!is_number(s), "{s:?}");
                assert_eq!(serde_yaml::to_string(s).unwrap(), format!("{s}\n"));
                let key: std::collections::BTreeMap<&str, u8> = [(s.as_str(), 1)].into();
                assert_eq!(serde_yaml::to_string(&key).unwrap(), format!("{s}: 1\n"));
                plain += 1;
            }
        }
        assert!(plain > 1_000, "only {plain} plain strings");
        for s in [
            "null", "Null", "NULL", "true", "True", "TRUE", "false", "False", "FALSE",
        ] {
            assert!(quoted_keyword(s));
            assert_eq!(serde_yaml::to_string(s).unwrap(), format!("'{s}'\n"));
        }
    }

    #[test]
    fn words_and_keys_are_what_compact_reads_as_such() {
        let mut texts: Vec<String> = STRINGS
            .iter()
            .filter(|s| plain_word(s).is_some())
            .map(|s| s.to_string())
            .collect();
        texts.extend(
            [
                "1", "-5", "1.0", "-.inf", ".inf", ".nan", "1e-30", "null", "x/y",
            ]
            .map(String::from),
        );
        let mut r = Rng(11);
        for _ in 0..1_000 {
            let mut t = String::new();
            push_float(&mut t, r.f32());
            texts.push(t);
        }
        for t in &texts {
            let flow = crate::compact::compact_yaml(&format!("k:\n- {t}\n- {t}\n"));
            assert_eq!(
                flow == format!("k: [{t}, {t}]\n"),
                is_word(t),
                "{t:?}: {flow}"
            );
            let flow = crate::compact::compact_yaml(&format!("s:\n- {t}: 1\n  z: 2\n"));
            assert_eq!(
                flow == format!("s:\n- {{{t}: 1, z: 2}}\n"),
                is_word(t) && !is_number(t),
                "{t:?}: {flow}"
            );
        }
    }

    #[test]
    fn floats_are_written_as_serde_yaml_writes_them() {
        let mut r = Rng(3);
        let specials = [
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e-310,
            1e300,
        ];
        let mut values: Vec<f32> = (0..10_000).map(|_| r.f32()).collect();
        values.extend(specials.map(|v| v as f32));
        values.extend([0.000_244_140_63, 2_097_152.2, f32::MIN_POSITIVE / 8.0]);
        for v in values {
            let mut text = String::new();
            push_float(&mut text, v);
            assert_eq!(
                format!("{text}\n"),
                serde_yaml::to_string(&v).unwrap(),
                "{v:e}"
            );
            let mut wide = String::new();
            push_float(&mut wide, f64::from(v) * 1.000_000_1);
            assert_eq!(
                format!("{wide}\n"),
                serde_yaml::to_string(&(f64::from(v) * 1.000_000_1)).unwrap(),
                "{v:e}"
            );
        }
        for v in specials {
            let mut text = String::new();
            push_float(&mut text, v);
            assert_eq!(
                format!("{text}\n"),
                serde_yaml::to_string(&v).unwrap(),
                "{v:e}"
            );
        }
    }
}
