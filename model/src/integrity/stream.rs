//! The streamed walk: a `serde::Serializer` that reads each value as `serde_yaml::to_value`
//! represents it and makes the value walk's checks as the referencing parts serialise.

use super::{Flaw, Scope};
use compound::{BufferField, Entries, Items};
use serde::ser::{self, Serialize};

mod compound;

/// Why the streamed walk gave up: something it does not represent as `serde_yaml::to_value` does
/// (the value walk then decides), or an error of the serialisation itself (which `to_value` meets
/// too).
#[derive(Debug)]
pub(super) struct Unmirrored(&'static str);

impl std::fmt::Display for Unmirrored {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

impl std::error::Error for Unmirrored {}

impl ser::Error for Unmirrored {
    fn custom<T: std::fmt::Display>(_: T) -> Self {
        Unmirrored("the value's own serialisation failed")
    }
}

/// What a serialised value is to the walk's checks: what `Value::as_str` and `Value::as_u64` (which
/// see through tags) read of the value `to_value` makes of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Shape {
    /// A string; its text is in [`Stream::text`] when the value was serialised to be kept
    /// ([`Node::keep`]), until the next such string.
    Str,
    /// A non-negative integer.
    Count(u64),
    /// Anything else: null, a boolean, a negative or floating-point number, a sequence, a mapping.
    Other,
}

/// Where a value stands for the walk's own bookkeeping: the document, whose `world` and `call` are
/// walked, and the places the names of the world's buffers and structures are read from (the streamed
/// walk takes them from the case before it starts, and checks as it passes them that they are the
/// names the value walk would read there).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    /// The whole document: a mapping.
    Root,
    /// `world`: a mapping.
    World,
    /// `world.buffers` (list 0) or `world.structures` (list 1): a sequence.
    List(usize),
    /// Item `i` of list `l`, `Item(l, i)`: a mapping whose `name` is the list's `i`th name.
    Item(usize, usize),
    /// Any other value.
    Any,
}

/// The keys the walk treats apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    World,
    Call,
    Buffers,
    Structures,
    Name,
    Buffer,
    Offset,
    Src,
    Dst,
    Other,
}

impl Key {
    /// The key `key` is, told apart by its length first (every key of a case passes here).
    #[inline]
    fn of(key: &str) -> Key {
        let is = |k: Key, text: &str| if key == text { k } else { Key::Other };
        match key.len() {
            3 if key == "src" => Key::Src,
            3 => is(Key::Dst, "dst"),
            4 if key == "call" => Key::Call,
            4 => is(Key::Name, "name"),
            5 => is(Key::World, "world"),
            6 if key == "buffer" => Key::Buffer,
            6 => is(Key::Offset, "offset"),
            7 => is(Key::Buffers, "buffers"),
            10 => is(Key::Structures, "structures"),
            _ => Key::Other,
        }
    }
}

/// The walk of [`Scope::walk`] made while the referencing parts serialise, without the value tree:
/// each value is read as `serde_yaml::to_value` represents it (structs and maps as mappings, a
/// newtype variant as its value tagged `!variant`, a struct or tuple variant as its mapping or
/// sequence tagged so, a unit variant as the string of its name, `None` and units as null, `Some`
/// and newtype structs as their content, bytes as a sequence of numbers) and its flaws are those the
/// value walk finds there, in its order.
///
/// The value walk pushes a field's or a tag's flaw before it walks the value under it, and decides
/// whether a mapping is an address (exactly an `offset` and a string `buffer`) before it walks the
/// mapping's entries. The stream learns these only once the value, or the mapping, has been
/// serialised, so such a flaw is inserted where the value started in the list of flaws: everything
/// after it there was found inside that value, or (for an address) in the mapping's later entries.
pub(super) struct Stream<'a> {
    scope: &'a Scope<'a>,
    /// The names of the world's buffers and structures, as the case holds them.
    named: [&'a [&'a str]; 2],
    /// How many names of each list the walk has passed and found as the case holds them.
    seen: [usize; 2],
    /// The YAML path of the value being serialised.
    at: String,
    out: Vec<Flaw>,
    /// The text of the last value of [`Shape::Str`] serialised where a check reads it.
    text: String,
    /// The keys of the open mappings, each mapping's after its parent's: a key met twice in one
    /// mapping is one entry of the value (the later value at the earlier place), which the stream
    /// does not represent. A struct's keys are its fields' names; a map's are copied into `map_keys`,
    /// each ending at its `map_key_ends` offset.
    fields: Vec<&'static str>,
    map_keys: String,
    map_key_ends: Vec<usize>,
    /// Whether the document's `call` has been walked (the value walk walks `world` first).
    called: bool,
}

impl<'a> Stream<'a> {
    /// The flaws of `parts`, the referencing parts of a case, after those in `out`; `named`: the names
    /// of the world's buffers and of its structures, which `scope` holds.
    pub(super) fn walk<T: ?Sized + Serialize>(
        parts: &T,
        scope: &'a Scope<'a>,
        named: [&'a [&'a str]; 2],
        out: Vec<Flaw>,
    ) -> Result<Vec<Flaw>, Unmirrored> {
        let mut s = Stream {
            scope,
            named,
            seen: [0, 0],
            // Sized past the paths and the nesting of cases, so that they seldom grow during a walk.
            at: String::with_capacity(128),
            out,
            text: String::new(),
            fields: Vec::with_capacity(64),
            map_keys: String::new(),
            map_key_ends: Vec::new(),
            called: false,
        };
        parts.serialize(Node {
            s: &mut s,
            role: Role::Root,
            keep: false,
        })?;
        if s.seen != [named[0].len(), named[1].len()] {
            return Err(Unmirrored(
                "the world's names are not all where the value walk reads them",
            ));
        }
        Ok(s.out)
    }
}

/// The serializer of one value of the walk, standing at `s.at`.
struct Node<'s, 'a> {
    s: &'s mut Stream<'a>,
    role: Role,
    /// Whether a check reads the value's text, if it is a string (into `s.text`).
    keep: bool,
}

impl<'s, 'a> Node<'s, 'a> {
    /// A scalar (never where a name or a collection of the bookkeeping stands).
    fn scalar(self, shape: Shape) -> Result<Shape, Unmirrored> {
        match self.role {
            Role::Any => Ok(shape),
            _ => Err(Unmirrored(
                "a scalar where a mapping or a list of names stands",
            )),
        }
    }

    /// A string scalar.
    fn string(self, text: &str) -> Result<Shape, Unmirrored> {
        if self.keep {
            self.s.text.clear();
            self.s.text.push_str(text);
        }
        self.scalar(Shape::Str)
    }

    /// A variant tagged with its name: `to_value` refuses an empty one.
    fn tag(&self, variant: &str) -> Result<(), Unmirrored> {
        match self.role {
            _ if variant.is_empty() => Err(Unmirrored("a variant without a name")),
            Role::Any => Ok(()),
            _ => Err(Unmirrored(
                "a variant where a mapping or a list of names stands",
            )),
        }
    }

    /// A mapping; `tag_check` when it was opened with one entry, where `to_value` reads a key written
    /// through `collect_str` as `!tag` as a tag (`serde_yaml`'s own tagged values).
    fn mapping(self, tag_check: bool) -> Result<Entries<'s, 'a>, Unmirrored> {
        if let Role::List(_) = self.role {
            return Err(Unmirrored("a mapping where a list of names stands"));
        }
        let s = self.s;
        let structure = s.at.ends_with(']') && s.at.starts_with("world.structures[");
        Ok(Entries {
            len: s.at.len(),
            fields_from: s.fields.len(),
            keys_from: s.map_keys.len(),
            ends_from: s.map_key_ends.len(),
            structure,
            role: self.role,
            tag_check,
            entries: 0,
            offset: false,
            buffer: BufferField::Absent,
            named: false,
            bloom: 0,
            s,
        })
    }

    /// A sequence.
    fn sequence(self) -> Result<Items<'s, 'a>, Unmirrored> {
        let list = match self.role {
            Role::Any => None,
            Role::List(l) => Some(l),
            _ => return Err(Unmirrored("a sequence where a mapping stands")),
        };
        Ok(Items {
            len: self.s.at.len(),
            index: 0,
            list,
            s: self.s,
        })
    }
}

impl<'s, 'a> ser::Serializer for Node<'s, 'a> {
    type Ok = Shape;
    type Error = Unmirrored;
    type SerializeSeq = Items<'s, 'a>;
    type SerializeTuple = Items<'s, 'a>;
    type SerializeTupleStruct = Items<'s, 'a>;
    type SerializeTupleVariant = Items<'s, 'a>;
    type SerializeMap = Entries<'s, 'a>;
    type SerializeStruct = Entries<'s, 'a>;
    type SerializeStructVariant = Entries<'s, 'a>;

    fn serialize_bool(self, _: bool) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Other)
    }
    fn serialize_i8(self, v: i8) -> Result<Shape, Unmirrored> {
        self.serialize_i64(v.into())
    }
    fn serialize_i16(self, v: i16) -> Result<Shape, Unmirrored> {
        self.serialize_i64(v.into())
    }
    fn serialize_i32(self, v: i32) -> Result<Shape, Unmirrored> {
        self.serialize_i64(v.into())
    }
    fn serialize_i64(self, v: i64) -> Result<Shape, Unmirrored> {
        self.scalar(u64::try_from(v).map_or(Shape::Other, Shape::Count))
    }
    fn serialize_i128(self, v: i128) -> Result<Shape, Unmirrored> {
        // `to_value` writes what no 64-bit integer holds as a string.
        if let Ok(v) = u64::try_from(v) {
            self.scalar(Shape::Count(v))
        } else if i64::try_from(v).is_ok() {
            self.scalar(Shape::Other)
        } else {
            self.string(&v.to_string())
        }
    }
    fn serialize_u8(self, v: u8) -> Result<Shape, Unmirrored> {
        self.serialize_u64(v.into())
    }
    fn serialize_u16(self, v: u16) -> Result<Shape, Unmirrored> {
        self.serialize_u64(v.into())
    }
    fn serialize_u32(self, v: u32) -> Result<Shape, Unmirrored> {
        self.serialize_u64(v.into())
    }
    fn serialize_u64(self, v: u64) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Count(v))
    }
    fn serialize_u128(self, v: u128) -> Result<Shape, Unmirrored> {
        match u64::try_from(v) {
            Ok(v) => self.scalar(Shape::Count(v)),
            Err(_) => self.string(&v.to_string()),
        }
    }
    fn serialize_f32(self, _: f32) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Other)
    }
    fn serialize_f64(self, _: f64) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Other)
    }
    fn serialize_char(self, v: char) -> Result<Shape, Unmirrored> {
        self.string(v.encode_utf8(&mut [0; 4]))
    }
    fn serialize_str(self, v: &str) -> Result<Shape, Unmirrored> {
        self.string(v)
    }
    /// A sequence of numbers, which holds nothing the walk checks.
    fn serialize_bytes(self, _: &[u8]) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Other)
    }
    fn serialize_none(self) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Other)
    }
    fn serialize_some<T: ?Sized + Serialize>(self, value: &T) -> Result<Shape, Unmirrored> {
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Other)
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<Shape, Unmirrored> {
        self.scalar(Shape::Other)
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
    ) -> Result<Shape, Unmirrored> {
        self.string(variant)
    }
    fn serialize_newtype_struct<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        value: &T,
    ) -> Result<Shape, Unmirrored> {
        value.serialize(self)
    }
    /// `!variant value`: the tag's check, placed before the flaws of its value.
    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        value: &T,
    ) -> Result<Shape, Unmirrored> {
        self.tag(variant)?;
        let s = self.s;
        let mark = s.out.len();
        let shape = value.serialize(Node {
            s: &mut *s,
            role: Role::Any,
            keep: self.keep || variant.trim_start_matches('!') == "structure",
        })?;
        let (number, name) = match shape {
            Shape::Count(n) => (Some(n), None),
            Shape::Str => (None, Some(s.text.as_str())),
            Shape::Other => (None, None),
        };
        if let Some(f) = s.scope.tagged(variant, number, name, &s.at) {
            s.out.insert(mark, f);
        }
        Ok(shape)
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<Items<'s, 'a>, Unmirrored> {
        self.sequence()
    }
    fn serialize_tuple(self, _: usize) -> Result<Items<'s, 'a>, Unmirrored> {
        self.sequence()
    }
    fn serialize_tuple_struct(
        self,
        _: &'static str,
        _: usize,
    ) -> Result<Items<'s, 'a>, Unmirrored> {
        self.sequence()
    }
    /// `!variant [...]`: a tag on a sequence names nothing the walk checks.
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Items<'s, 'a>, Unmirrored> {
        self.tag(variant)?;
        self.sequence()
    }
    fn serialize_map(self, len: Option<usize>) -> Result<Entries<'s, 'a>, Unmirrored> {
        self.mapping(len == Some(1))
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Entries<'s, 'a>, Unmirrored> {
        self.mapping(false)
    }
    /// `!variant {...}`: a tag on a mapping names nothing the walk checks.
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Entries<'s, 'a>, Unmirrored> {
        self.tag(variant)?;
        self.mapping(false)
    }
}
