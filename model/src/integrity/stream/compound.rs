//! The streamed walk's compound values: a sequence's items, a mapping's entries (with the address
//! check made at the mapping's end) and a map key's text.

use super::*;

/// The bit of a key in a mapping's [`Entries::bloom`].
#[inline(always)]
pub(super) fn key_bit(key: &str) -> u64 {
    let last = key.as_bytes().last().copied().unwrap_or(0);
    let hash = (key.len() as u32) << 8 | u32::from(last);
    1 << (hash.wrapping_mul(0x9e37_79b9) >> 26)
}

/// The elements of a sequence, each at `[i]` after the sequence's path.
pub(super) struct Items<'s, 'a> {
    pub(super) s: &'s mut Stream<'a>,
    /// The length of the sequence's path.
    pub(super) len: usize,
    pub(super) index: usize,
    /// The list of names this is (`world.buffers`, `world.structures`), if one.
    pub(super) list: Option<usize>,
}

impl Items<'_, '_> {
    fn element<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), Unmirrored> {
        push_index(&mut self.s.at, self.index);
        let role = match self.list {
            Some(l) => Role::Item(l, self.index),
            None => Role::Any,
        };
        value.serialize(Node {
            s: &mut *self.s,
            role,
            keep: false,
        })?;
        self.s.at.truncate(self.len);
        self.index += 1;
        Ok(())
    }
}

/// Appends `[i]` to a path.
pub(super) fn push_index(at: &mut String, i: usize) {
    at.push('[');
    if i < 10 {
        at.push(char::from(b'0' + i as u8));
    } else {
        let mut digits = [0u8; 20];
        let mut k = digits.len();
        let mut n = i;
        while n > 0 {
            k -= 1;
            digits[k] = b'0' + (n % 10) as u8;
            n /= 10;
        }
        at.extend(digits[k..].iter().map(|&d| char::from(d)));
    }
    at.push(']');
}

/// The four sequence-like compounds of serde, each an [`Items`] whose elements are walked in turn.
macro_rules! items_compound {
    ($($compound:ident :: $element:ident),*) => {$(
        impl ser::$compound for Items<'_, '_> {
            type Ok = Shape;
            type Error = Unmirrored;
            fn $element<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), Unmirrored> {
                self.element(value)
            }
            fn end(self) -> Result<Shape, Unmirrored> {
                Ok(Shape::Other)
            }
        }
    )*};
}

items_compound!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

/// What a mapping's `buffer` entry is to the address check made at the mapping's end.
pub(super) enum BufferField {
    Absent,
    /// Not a string: the mapping is no address.
    Other,
    /// A string, with the flaw it makes if the mapping is an address (a buffer the world lacks) and
    /// where that flaw goes in the list of flaws.
    Str(Option<(usize, Flaw)>),
}

/// The entries of a mapping, each at `.key` after the mapping's path (the document's at `key`).
pub(super) struct Entries<'s, 'a> {
    pub(super) s: &'s mut Stream<'a>,
    /// The length of the mapping's path.
    pub(super) len: usize,
    pub(super) role: Role,
    /// Whether the mapping's path starts `world.structures[` and ends `]` (an item of the world's
    /// structures, or an item of a sequence inside one): its `buffer` names a buffer.
    pub(super) structure: bool,
    /// See [`Node::mapping`].
    pub(super) tag_check: bool,
    /// How many entries it has had.
    pub(super) entries: usize,
    /// Whether it has an `offset` entry.
    pub(super) offset: bool,
    pub(super) buffer: BufferField,
    /// For an item of a list of names: whether its `name` has been passed.
    pub(super) named: bool,
    /// Where this mapping's keys start in `s.fields`, `s.map_keys` and `s.map_key_ends`.
    pub(super) fields_from: usize,
    pub(super) keys_from: usize,
    pub(super) ends_from: usize,
    /// A bit per key seen, by a hash of its length and last byte: only a key whose bit is set is
    /// looked for among the earlier ones.
    pub(super) bloom: u64,
}

impl Entries<'_, '_> {
    /// The length of the path before the key of an entry.
    fn key_from(&self) -> usize {
        match self.role {
            Role::Root => self.len,
            _ => self.len + 1,
        }
    }

    /// Starts an entry's path: the separator before its key, which the caller then appends.
    fn open(&mut self) {
        if self.role != Role::Root {
            self.s.at.push('.');
        }
    }

    /// The entry whose key ends the path: its value serialised, walked and checked.
    fn value<T: ?Sized + Serialize>(&mut self, key: Key, value: &T) -> Result<(), Unmirrored> {
        if self.role == Role::Root {
            self.document_entry(key, value)?;
        } else {
            self.entry(key, value)?;
        }
        self.s.at.truncate(self.len);
        Ok(())
    }

    /// An entry of the document: `world` and `call` are walked, in that order; anything else is
    /// serialised, as `to_value` serialises it, but not walked.
    fn document_entry<T: ?Sized + Serialize>(
        &mut self,
        key: Key,
        value: &T,
    ) -> Result<(), Unmirrored> {
        let s = &mut *self.s;
        let role = match key {
            Key::World if s.called => {
                return Err(Unmirrored("the document's `call` before its `world`"))
            }
            Key::World => Role::World,
            Key::Call => {
                s.called = true;
                Role::Any
            }
            _ => {
                let mark = s.out.len();
                value.serialize(Node {
                    s: &mut *s,
                    role: Role::Any,
                    keep: false,
                })?;
                s.out.truncate(mark);
                return Ok(());
            }
        };
        value.serialize(Node {
            s,
            role,
            keep: false,
        })?;
        Ok(())
    }

    /// An entry of a walked mapping, as [`Scope::walk`] walks it.
    fn entry<T: ?Sized + Serialize>(&mut self, key: Key, value: &T) -> Result<(), Unmirrored> {
        self.entries += 1;
        self.offset |= key == Key::Offset;
        let role = match (self.role, key) {
            (Role::World, Key::Buffers) => Role::List(0),
            (Role::World, Key::Structures) => Role::List(1),
            _ => Role::Any,
        };
        let s = &mut *self.s;
        let mark = s.out.len();
        let keep = match key {
            Key::Buffer | Key::Src | Key::Dst => true,
            Key::Name => matches!(self.role, Role::Item(..)),
            _ => false,
        };
        let shape = value.serialize(Node {
            s: &mut *s,
            role,
            keep,
        })?;
        // Descriptors may name destroyed objects on purpose (rules judge them).
        if s.at == "world.resources" {
            s.out.truncate(mark);
            return Ok(());
        }
        match (key, shape) {
            (Key::Buffer, Shape::Str) => {
                // A structure's buffer is checked now; an address's once the mapping is known to be one.
                let flaw = s.scope.field("buffer", true, Some(&s.text), &s.at);
                self.buffer = match flaw {
                    Some(f) if self.structure => {
                        s.out.insert(mark, f);
                        BufferField::Str(None)
                    }
                    flaw => BufferField::Str(flaw.map(|f| (mark, f))),
                };
            }
            (Key::Buffer, _) => self.buffer = BufferField::Other,
            (Key::Src | Key::Dst, Shape::Str) => {
                let key = if key == Key::Src { "src" } else { "dst" };
                if let Some(f) = s.scope.field(key, false, Some(&s.text), &s.at) {
                    s.out.insert(mark, f);
                }
            }
            (Key::Name, shape) => {
                if let Role::Item(l, i) = self.role {
                    let as_held = shape == Shape::Str
                        && s.seen[l] == i
                        && s.named[l].get(i) == Some(&s.text.as_str());
                    if !as_held {
                        return Err(Unmirrored("a name of the world other than the case holds"));
                    }
                    s.seen[l] += 1;
                    self.named = true;
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Records a struct's field; an error if the mapping already has it.
    #[inline(always)]
    fn note_field(&mut self, field: &'static str) -> Result<(), Unmirrored> {
        let bit = key_bit(field);
        let s = &mut *self.s;
        if self.bloom & bit != 0 && s.fields[self.fields_from..].contains(&field) {
            return Err(Unmirrored("a key twice in one mapping"));
        }
        self.bloom |= bit;
        s.fields.push(field);
        Ok(())
    }

    /// Records the map key that ends the path; an error if the mapping already has it.
    fn note_map_key(&mut self) -> Result<(), Unmirrored> {
        let from = self.key_from();
        let s = &mut *self.s;
        let key = &s.at[from..];
        let bit = key_bit(key);
        if self.bloom & bit != 0 {
            let mut start = self.keys_from;
            let twice = s.map_key_ends[self.ends_from..].iter().any(|&end| {
                let earlier = &s.map_keys[start..end];
                start = end;
                earlier == key
            });
            if twice {
                return Err(Unmirrored("a key twice in one mapping"));
            }
        }
        self.bloom |= bit;
        s.map_keys.push_str(key);
        s.map_key_ends.push(s.map_keys.len());
        Ok(())
    }

    /// Ends the mapping: the address check, and the check that an item of a list of names had one.
    fn close(self) -> Result<Shape, Unmirrored> {
        let s = self.s;
        if let BufferField::Str(Some((mark, flaw))) = self.buffer {
            if self.entries == 2 && self.offset {
                s.out.insert(mark, flaw);
            }
        }
        if let (Role::Item(..), false) = (self.role, self.named) {
            return Err(Unmirrored("an item of the world's names without a name"));
        }
        s.fields.truncate(self.fields_from);
        s.map_keys.truncate(self.keys_from);
        s.map_key_ends.truncate(self.ends_from);
        Ok(Shape::Other)
    }
}

impl ser::SerializeMap for Entries<'_, '_> {
    type Ok = Shape;
    type Error = Unmirrored;
    fn serialize_key<T: ?Sized + Serialize>(&mut self, key: &T) -> Result<(), Unmirrored> {
        self.open();
        key.serialize(KeyText {
            at: &mut self.s.at,
            tag_check: self.tag_check,
        })?;
        self.note_map_key()
    }
    fn serialize_value<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), Unmirrored> {
        let key = Key::of(&self.s.at[self.key_from()..]);
        self.value(key, value)
    }
    fn end(self) -> Result<Shape, Unmirrored> {
        self.close()
    }
}

impl ser::SerializeStruct for Entries<'_, '_> {
    type Ok = Shape;
    type Error = Unmirrored;
    fn serialize_field<T: ?Sized + Serialize>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Unmirrored> {
        self.note_field(key)?;
        self.open();
        self.s.at.push_str(key);
        self.value(Key::of(key), value)
    }
    fn end(self) -> Result<Shape, Unmirrored> {
        self.close()
    }
}

impl ser::SerializeStructVariant for Entries<'_, '_> {
    type Ok = Shape;
    type Error = Unmirrored;
    fn serialize_field<T: ?Sized + Serialize>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Unmirrored> {
        ser::SerializeStruct::serialize_field(self, key, value)
    }
    fn end(self) -> Result<Shape, Unmirrored> {
        self.close()
    }
}

/// The serializer of a map's key, appending it to the path: a key `to_value` makes a string (a
/// string, a character, a unit variant, or one of these in a newtype struct or `Some`). Any other key
/// is one the walk skips, or a tag (see [`Node::mapping`]); the stream gives up on those.
pub(super) struct KeyText<'s> {
    pub(super) at: &'s mut String,
    pub(super) tag_check: bool,
}

impl KeyText<'_> {
    fn unmirrored<T>(self) -> Result<T, Unmirrored> {
        Err(Unmirrored("a mapping key that is not a string"))
    }
}

impl<'s> ser::Serializer for KeyText<'s> {
    type Ok = ();
    type Error = Unmirrored;
    type SerializeSeq = ser::Impossible<(), Unmirrored>;
    type SerializeTuple = ser::Impossible<(), Unmirrored>;
    type SerializeTupleStruct = ser::Impossible<(), Unmirrored>;
    type SerializeTupleVariant = ser::Impossible<(), Unmirrored>;
    type SerializeMap = ser::Impossible<(), Unmirrored>;
    type SerializeStruct = ser::Impossible<(), Unmirrored>;
    type SerializeStructVariant = ser::Impossible<(), Unmirrored>;

    fn serialize_str(self, v: &str) -> Result<(), Unmirrored> {
        self.at.push_str(v);
        Ok(())
    }
    fn serialize_char(self, v: char) -> Result<(), Unmirrored> {
        self.at.push(v);
        Ok(())
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
    ) -> Result<(), Unmirrored> {
        self.serialize_str(variant)
    }
    fn serialize_newtype_struct<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        value: &T,
    ) -> Result<(), Unmirrored> {
        value.serialize(self)
    }
    fn serialize_some<T: ?Sized + Serialize>(self, value: &T) -> Result<(), Unmirrored> {
        value.serialize(self)
    }
    fn collect_str<T: ?Sized + std::fmt::Display>(self, value: &T) -> Result<(), Unmirrored> {
        use std::fmt::Write;
        if self.tag_check {
            return Err(Unmirrored("a key written as text where it may be a tag"));
        }
        write!(self.at, "{value}").map_err(|_| Unmirrored("a key whose text fails"))
    }

    fn serialize_bool(self, _: bool) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_i8(self, _: i8) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_i16(self, _: i16) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_i32(self, _: i32) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_i64(self, _: i64) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_u8(self, _: u8) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_u16(self, _: u16) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_u32(self, _: u32) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_u64(self, _: u64) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_f32(self, _: f32) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_f64(self, _: f64) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_bytes(self, _: &[u8]) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_none(self) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_unit(self) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> Result<(), Unmirrored> {
        self.unmirrored()
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<Self::SerializeSeq, Unmirrored> {
        self.unmirrored()
    }
    fn serialize_tuple(self, _: usize) -> Result<Self::SerializeTuple, Unmirrored> {
        self.unmirrored()
    }
    fn serialize_tuple_struct(
        self,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleStruct, Unmirrored> {
        self.unmirrored()
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleVariant, Unmirrored> {
        self.unmirrored()
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, Unmirrored> {
        self.unmirrored()
    }
    fn serialize_struct(
        self,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStruct, Unmirrored> {
        self.unmirrored()
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStructVariant, Unmirrored> {
        self.unmirrored()
    }
}
