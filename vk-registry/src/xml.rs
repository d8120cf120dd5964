//! vk.xml read with quick-xml (borrowed events over the text in memory) into a typed,
//! indexed, deterministic [`Registry`]: types, enums with every value (extension values
//! computed from offset/extnumber/dir), commands, features and extensions.
//!
//! Elements whose `api` attribute does not include `vulkan` are dropped. Sections that are not
//! modelled (platforms, tags, formats, SPIR-V tables, sync, video codecs) are skipped as a
//! whole; any other unexpected element is a located error.

use crate::error::{line_col, read_to_string, RegistryError};
use crate::vuid::Condition;
use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// A small multiplicative hasher for the name indexes (names are trusted registry input).
#[derive(Default, Clone, Copy)]
struct NameHasher(u64);

impl Hasher for NameHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        const K: u64 = 0x517c_c1b7_2722_0a95;
        let mut h = self.0;
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            let w = u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
            h = (h.rotate_left(5) ^ w).wrapping_mul(K);
        }
        for &b in chunks.remainder() {
            h = (h.rotate_left(5) ^ u64::from(b)).wrapping_mul(K);
        }
        self.0 = h;
    }
}

type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<NameHasher>>;
use std::fmt::Write;
use std::path::Path;

/// The kind of a `<type>`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TypeCategory {
    Struct,
    Union,
    Handle,
    Enum,
    Bitmask,
    BaseType,
    Define,
    Include,
    FuncPointer,
    /// A type with no category (platform types such as `Display`, C types such as `uint32_t`).
    External,
}

/// A structure member or a command parameter.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Member {
    pub name: String,
    /// The base type name (`VkDeviceAddress`, `uint32_t`...).
    pub type_name: String,
    /// The whole C declaration, whitespace collapsed (`const VkFoo* pFoo`).
    pub decl: String,
    /// Whether the declaration starts with `const`.
    pub is_const: bool,
    /// Number of `*` in the declaration.
    pub pointer_depth: u8,
    /// Array sizes, outermost first (`4`, `VK_UUID_SIZE`).
    pub array: Vec<String>,
    /// Bit-field width, if any.
    pub bitfield: Option<u8>,
    /// The `optional` attribute split on commas.
    pub optional: Vec<bool>,
    pub len: Option<String>,
    pub altlen: Option<String>,
    pub values: Option<String>,
    pub noautovalidity: bool,
    pub limittype: Option<String>,
    pub selector: Option<String>,
    pub selection: Option<String>,
    pub externsync: Option<String>,
    pub objecttype: Option<String>,
    pub stride: Option<String>,
    pub validstructs: Vec<String>,
    pub api: Option<String>,
    pub deprecated: Option<String>,
}

/// A command parameter has the same shape as a structure member.
pub type Param = Member;

/// A `<type>` entry.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TypeDef {
    pub name: String,
    pub category: TypeCategory,
    pub alias: Option<String>,
    pub api: Option<String>,
    /// Handles: the parent handle(s).
    pub parent: Vec<String>,
    /// Handles: `VK_DEFINE_HANDLE` (true) or `VK_DEFINE_NON_DISPATCHABLE_HANDLE` (false).
    pub dispatchable: Option<bool>,
    pub objtypeenum: Option<String>,
    /// The `<type>` child: the underlying type of a bitmask/basetype, the handle macro...
    pub base: Option<String>,
    pub requires: Option<String>,
    /// Bitmasks: the FlagBits enum (`requires` in old registries, `bitvalues` in new ones).
    pub bitvalues: Option<String>,
    pub structextends: Vec<String>,
    pub returnedonly: bool,
    pub allowduplicate: bool,
    pub deprecated: Option<String>,
    pub members: Vec<Member>,
}

/// How an `<enums>` block is used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum EnumKind {
    Constants,
    Enum,
    Bitmask,
}

/// One enumerant.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EnumValue {
    pub name: String,
    /// The numeric value (aliases resolved; `None` for strings and floats).
    pub value: Option<i64>,
    pub bitpos: Option<u32>,
    pub alias: Option<String>,
    /// The literal text of `value` when it is not a plain integer (`"(~0U)"`, `"1000.0F"`).
    pub raw: Option<String>,
    /// API constants: their C type.
    pub c_type: Option<String>,
    /// The feature or extension that added this value (None for the base definition).
    pub added_by: Option<String>,
    pub protect: Option<String>,
    pub deprecated: Option<String>,
}

/// An `<enums>` block with every value, those added by features and extensions included.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EnumGroup {
    pub name: String,
    pub kind: EnumKind,
    pub bitwidth: Option<u32>,
    pub values: Vec<EnumValue>,
}

/// A `<command>`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Command {
    pub name: String,
    /// For an alias entry, the command it aliases (its other fields are then empty).
    pub alias: Option<String>,
    pub api: Option<String>,
    pub return_type: String,
    pub params: Vec<Param>,
    pub successcodes: Vec<String>,
    pub errorcodes: Vec<String>,
    pub queues: Vec<String>,
    pub renderpass: Option<String>,
    pub videocoding: Option<String>,
    pub cmdbufferlevel: Vec<String>,
    pub tasks: Vec<String>,
    pub implicit_externsync: Vec<String>,
}

/// A `<feature name=... struct=...>` reference inside a require block.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FeatureRef {
    pub name: String,
    pub structure: String,
}

/// A `<require>` or `<remove>` block.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Require {
    pub depends: Option<Condition>,
    pub api: Option<String>,
    pub comment: Option<String>,
    pub types: Vec<String>,
    pub commands: Vec<String>,
    pub enums: Vec<String>,
    pub features: Vec<FeatureRef>,
}

/// A `<feature>` (an API version).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Feature {
    pub name: String,
    pub number: String,
    pub api: Vec<String>,
    pub depends: Option<Condition>,
    pub require: Vec<Require>,
    pub remove: Vec<Require>,
}

/// An `<extension>`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Extension {
    pub name: String,
    pub number: u32,
    /// `instance` or `device`.
    pub ext_type: Option<String>,
    pub supported: Vec<String>,
    pub depends: Option<Condition>,
    pub promotedto: Option<String>,
    pub deprecatedby: Option<String>,
    pub obsoletedby: Option<String>,
    pub platform: Option<String>,
    pub provisional: bool,
    pub specialuse: Vec<String>,
    pub ratified: Vec<String>,
    pub author: Option<String>,
    pub contact: Option<String>,
    pub require: Vec<Require>,
    pub remove: Vec<Require>,
}

impl Extension {
    /// Whether the extension is supported by the `vulkan` API (not disabled, not SC-only).
    pub fn is_vulkan(&self) -> bool {
        self.supported.iter().any(|s| s == "vulkan")
    }
}

/// The whole registry, in document order, with name indexes.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Registry {
    pub types: Vec<TypeDef>,
    pub enum_groups: Vec<EnumGroup>,
    /// Enumerants defined by features/extensions without `extends` (`*_SPEC_VERSION`, ...).
    pub ext_constants: Vec<EnumValue>,
    pub commands: Vec<Command>,
    pub features: Vec<Feature>,
    pub extensions: Vec<Extension>,
    #[serde(skip)]
    index: Index,
}

#[derive(Debug, Clone, Default)]
struct Index {
    types: FastMap<String, usize>,
    groups: FastMap<String, usize>,
    /// value name -> (group index or usize::MAX for ext_constants, value index)
    values: FastMap<String, (usize, usize)>,
    commands: FastMap<String, usize>,
    features: FastMap<String, usize>,
    extensions: FastMap<String, usize>,
}

impl Registry {
    /// Read vk.xml from a file.
    pub fn load(path: impl AsRef<Path>) -> Result<Registry, RegistryError> {
        let path = path.as_ref();
        let text = read_to_string(path)?;
        Parser::new(&text, &path.display().to_string()).run()
    }

    /// Parse vk.xml text.
    pub fn parse(text: &str) -> Result<Registry, RegistryError> {
        Parser::new(text, "<string>").run()
    }

    /// Parse vk.xml text, naming it `origin` in errors.
    pub fn parse_named(text: &str, origin: &str) -> Result<Registry, RegistryError> {
        Parser::new(text, origin).run()
    }

    /// A command by name (alias entries are returned as they are; see [`Registry::command_resolved`]).
    pub fn command(&self, name: &str) -> Option<&Command> {
        self.index.commands.get(name).map(|&i| &self.commands[i])
    }

    /// A command by name, following aliases.
    pub fn command_resolved(&self, name: &str) -> Option<&Command> {
        let mut c = self.command(name)?;
        for _ in 0..8 {
            match &c.alias {
                Some(a) => c = self.command(a)?,
                None => return Some(c),
            }
        }
        None
    }

    /// Any type by name.
    pub fn type_def(&self, name: &str) -> Option<&TypeDef> {
        self.index.types.get(name).map(|&i| &self.types[i])
    }

    /// A struct or union by name (aliases followed).
    pub fn structure(&self, name: &str) -> Option<&TypeDef> {
        let mut t = self.type_def(name)?;
        for _ in 0..8 {
            if let Some(a) = &t.alias {
                t = self.type_def(a)?;
            } else {
                break;
            }
        }
        matches!(t.category, TypeCategory::Struct | TypeCategory::Union).then_some(t)
    }

    /// An `<enums>` group by name (`VkStructureType`, `VkBufferUsageFlagBits`, `API Constants`).
    pub fn enum_group(&self, name: &str) -> Option<&EnumGroup> {
        self.index.groups.get(name).map(|&i| &self.enum_groups[i])
    }

    /// The enumerant record of any enum value or extension constant.
    pub fn enum_entry(&self, name: &str) -> Option<&EnumValue> {
        let &(g, v) = self.index.values.get(name)?;
        Some(if g == usize::MAX {
            &self.ext_constants[v]
        } else {
            &self.enum_groups[g].values[v]
        })
    }

    /// The numeric value of an enumerant (aliases resolved).
    pub fn enum_value(&self, name: &str) -> Option<i64> {
        self.enum_entry(name)?.value
    }

    /// The group an enumerant belongs to.
    pub fn enum_group_of(&self, value_name: &str) -> Option<&EnumGroup> {
        let &(g, _) = self.index.values.get(value_name)?;
        self.enum_groups.get(g)
    }

    /// The bits of a bitmask: `typename` may be the Flags type (`VkBufferUsageFlags`) or the
    /// FlagBits enum (`VkBufferUsageFlagBits`). Returns (name, value) in document order.
    pub fn bitmask_bits(&self, typename: &str) -> Option<Vec<(String, i64)>> {
        let group_name = match self.type_def(typename) {
            Some(t) if t.category == TypeCategory::Bitmask => {
                let t = match &t.alias {
                    Some(a) => self.type_def(a)?,
                    None => t,
                };
                match &t.bitvalues {
                    Some(b) => b.clone(),
                    None => return Some(Vec::new()),
                }
            }
            _ => typename.to_string(),
        };
        let g = self.enum_group(&group_name)?;
        Some(
            g.values
                .iter()
                .filter_map(|v| v.value.map(|x| (v.name.clone(), x)))
                .collect(),
        )
    }

    pub fn feature(&self, name: &str) -> Option<&Feature> {
        self.index.features.get(name).map(|&i| &self.features[i])
    }

    pub fn extension(&self, name: &str) -> Option<&Extension> {
        self.index
            .extensions
            .get(name)
            .map(|&i| &self.extensions[i])
    }

    /// Readable text about a command, a type or an enum value (used by `report::show`).
    pub fn describe(&self, name: &str) -> Option<String> {
        let mut o = String::new();
        if let Some(c) = self.command(name) {
            let _ = writeln!(o, "command {}", c.name);
            if let Some(a) = &c.alias {
                let _ = writeln!(o, "  alias of {a}");
                return Some(o);
            }
            let _ = writeln!(o, "  returns {}", c.return_type);
            for p in &c.params {
                let _ = writeln!(o, "  param {}{}", p.decl, member_attrs(p));
            }
            let list = |o: &mut String, k: &str, v: &[String]| {
                if !v.is_empty() {
                    let _ = writeln!(o, "  {k}: {}", v.join(","));
                }
            };
            list(&mut o, "queues", &c.queues);
            if let Some(r) = &c.renderpass {
                let _ = writeln!(o, "  renderpass: {r}");
            }
            if let Some(r) = &c.videocoding {
                let _ = writeln!(o, "  videocoding: {r}");
            }
            list(&mut o, "cmdbufferlevel", &c.cmdbufferlevel);
            list(&mut o, "tasks", &c.tasks);
            list(&mut o, "successcodes", &c.successcodes);
            list(&mut o, "errorcodes", &c.errorcodes);
            self.provided_by(&mut o, name);
            return Some(o);
        }
        if let Some(t) = self.type_def(name) {
            let _ = writeln!(o, "{:?} {}", t.category, t.name).map(|_| ());
            let o2 = o.replacen(
                &format!("{:?}", t.category),
                &format!("{:?}", t.category).to_lowercase(),
                1,
            );
            o = o2;
            if let Some(a) = &t.alias {
                let _ = writeln!(o, "  alias of {a}");
            }
            if let Some(b) = &t.base {
                let _ = writeln!(o, "  base: {b}");
            }
            if !t.parent.is_empty() {
                let _ = writeln!(o, "  parent: {}", t.parent.join(","));
            }
            if let Some(d) = t.dispatchable {
                let _ = writeln!(o, "  dispatchable: {d}");
            }
            if t.returnedonly {
                let _ = writeln!(o, "  returnedonly");
            }
            if !t.structextends.is_empty() {
                let _ = writeln!(o, "  structextends: {}", t.structextends.join(","));
            }
            for m in &t.members {
                let _ = writeln!(o, "  member {}{}", m.decl, member_attrs(m));
            }
            if let Some(bits) = t
                .bitvalues
                .as_deref()
                .or(if t.category == TypeCategory::Enum {
                    Some(&t.name)
                } else {
                    None
                })
            {
                if let Some(g) = self.enum_group(bits) {
                    let _ = writeln!(o, "  values ({}):", g.name);
                    for v in &g.values {
                        let _ = writeln!(o, "    {} = {}", v.name, fmt_value(v));
                    }
                }
            }
            self.provided_by(&mut o, name);
            return Some(o);
        }
        if let Some(v) = self.enum_entry(name) {
            let group = self
                .enum_group_of(name)
                .map(|g| g.name.as_str())
                .unwrap_or("(extension constant)");
            let _ = writeln!(o, "enum {} = {}", v.name, fmt_value(v));
            let _ = writeln!(o, "  group: {group}");
            if let Some(a) = &v.alias {
                let _ = writeln!(o, "  alias of {a}");
            }
            if let Some(a) = &v.added_by {
                let _ = writeln!(o, "  added by {a}");
            }
            return Some(o);
        }
        if let Some(g) = self.enum_group(name) {
            let _ = writeln!(o, "enums {} ({:?})", g.name, g.kind);
            for v in &g.values {
                let _ = writeln!(o, "    {} = {}", v.name, fmt_value(v));
            }
            return Some(o);
        }
        None
    }

    fn provided_by(&self, o: &mut String, name: &str) {
        let has = |r: &Require| r.types.iter().chain(&r.commands).any(|n| n == name);
        let mut by: Vec<&str> = Vec::new();
        for f in &self.features {
            if f.require.iter().any(has) {
                by.push(&f.name);
            }
        }
        for e in &self.extensions {
            if e.is_vulkan() && e.require.iter().any(has) {
                by.push(&e.name);
            }
        }
        if !by.is_empty() {
            let _ = writeln!(o, "  provided by: {}", by.join(", "));
        }
    }

    fn build_index(
        &mut self,
        values: FastMap<String, (usize, usize)>,
        groups: FastMap<String, usize>,
    ) {
        let mut ix = Index {
            values,
            groups,
            ..Index::default()
        };
        for (i, t) in self.types.iter().enumerate() {
            ix.types.entry(t.name.clone()).or_insert(i);
        }
        for (i, c) in self.commands.iter().enumerate() {
            ix.commands.entry(c.name.clone()).or_insert(i);
        }
        for (i, f) in self.features.iter().enumerate() {
            ix.features.entry(f.name.clone()).or_insert(i);
        }
        for (i, e) in self.extensions.iter().enumerate() {
            ix.extensions.entry(e.name.clone()).or_insert(i);
        }
        self.index = ix;
    }
}

fn fmt_value(v: &EnumValue) -> String {
    match (v.value, &v.raw) {
        (Some(x), _)
            if v.bitpos.is_some() || (x > 0xffff && x < 0x1_0000_0000 && x.count_ones() == 1) =>
        {
            format!("{x:#x}")
        }
        (Some(x), _) => x.to_string(),
        (None, Some(r)) => r.clone(),
        (None, None) => v
            .alias
            .clone()
            .map(|a| format!("alias {a}"))
            .unwrap_or_else(|| "?".into()),
    }
}

fn member_attrs(m: &Member) -> String {
    let mut s = Vec::new();
    if !m.optional.is_empty() {
        s.push(format!(
            "optional={}",
            m.optional
                .iter()
                .map(|b| b.to_string())
                .collect::<Vec<_>>()
                .join(",")
        ));
    }
    for (k, v) in [
        ("len", &m.len),
        ("altlen", &m.altlen),
        ("values", &m.values),
        ("limittype", &m.limittype),
        ("selector", &m.selector),
        ("selection", &m.selection),
        ("externsync", &m.externsync),
        ("stride", &m.stride),
    ] {
        if let Some(v) = v {
            s.push(format!("{k}={v}"));
        }
    }
    if m.noautovalidity {
        s.push("noautovalidity".into());
    }
    if s.is_empty() {
        String::new()
    } else {
        format!("  [{}]", s.join(" "))
    }
}

// ---------------------------------------------------------------------------------------------
// Parsing

enum Ev<'a> {
    Open(BytesStart<'a>, bool),
    Close,
    Text(quick_xml::events::BytesText<'a>),
}

struct Parser<'a> {
    src: &'a str,
    origin: &'a str,
    r: Reader<&'a [u8]>,
    reg: Registry,
    /// enum value name -> (group, index), maintained while parsing for de-duplication
    values: FastMap<String, (usize, usize)>,
    groups: FastMap<String, usize>,
    pending_ext: Vec<(String, PendingValue)>,
}

/// A value added by a feature or extension, applied once all `<enums>` are read.
struct PendingValue {
    value: EnumValue,
    offset_pos: usize,
}

fn is_vulkan_api(api: Option<&str>) -> bool {
    api.unwrap_or("vulkan")
        .split(',')
        .any(|x| x.trim() == "vulkan")
}

fn split_list(s: &str) -> Vec<String> {
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
    let v = if neg { -v } else { v };
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

impl<'a> Parser<'a> {
    fn new(src: &'a str, origin: &'a str) -> Self {
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

    fn err_at(&self, pos: usize, msg: impl Into<String>) -> RegistryError {
        let (line, column) = line_col(self.src, pos);
        RegistryError::at_line_col(self.origin, line, column, msg)
    }

    fn err_here(&self, msg: impl Into<String>) -> RegistryError {
        self.err_at(self.r.buffer_position() as usize, msg)
    }

    fn xml_err(&self, e: quick_xml::Error) -> RegistryError {
        self.err_at(
            self.r.error_position() as usize,
            format!("malformed XML: {e}"),
        )
    }

    fn next(&mut self) -> Result<Option<Ev<'a>>, RegistryError> {
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
    fn child(&mut self, ctx: &str) -> Result<Ev<'a>, RegistryError> {
        match self.next()? {
            Some(ev) => Ok(ev),
            None => Err(self.err_here(format!("unexpected end of file inside <{ctx}>"))),
        }
    }

    fn skip(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
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

    fn unescape<'t>(
        &self,
        t: &'t quick_xml::events::BytesText<'a>,
    ) -> Result<Cow<'t, str>, RegistryError> {
        t.unescape().map_err(|e| self.xml_err(e))
    }

    fn start_pos(&self) -> usize {
        // buffer_position is just after the tag; find its '<' for error locations
        let p = (self.r.buffer_position() as usize).min(self.src.len());
        self.src[..p].rfind('<').unwrap_or(0)
    }

    fn unexpected(&self, e: &BytesStart, ctx: &str) -> RegistryError {
        self.err_at(
            self.start_pos(),
            format!(
                "unexpected element <{}> inside <{ctx}>",
                String::from_utf8_lossy(e.name().as_ref())
            ),
        )
    }

    fn attrs<'e>(
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

    fn run(mut self) -> Result<Registry, RegistryError> {
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

    fn registry(&mut self) -> Result<(), RegistryError> {
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

    fn container(
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

    fn type_def(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut t = TypeDef {
            name: String::new(),
            category: TypeCategory::External,
            alias: None,
            api: None,
            parent: Vec::new(),
            dispatchable: None,
            objtypeenum: None,
            base: None,
            requires: None,
            bitvalues: None,
            structextends: Vec::new(),
            returnedonly: false,
            allowduplicate: false,
            deprecated: None,
            members: Vec::new(),
        };
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => t.name = v.into_owned(),
                "category" => {
                    t.category = match &*v {
                        "struct" => TypeCategory::Struct,
                        "union" => TypeCategory::Union,
                        "handle" => TypeCategory::Handle,
                        "enum" => TypeCategory::Enum,
                        "bitmask" => TypeCategory::Bitmask,
                        "basetype" => TypeCategory::BaseType,
                        "define" => TypeCategory::Define,
                        "include" => TypeCategory::Include,
                        "funcpointer" => TypeCategory::FuncPointer,
                        other => {
                            return Err(self.err_at(pos, format!("unknown type category `{other}`")))
                        }
                    }
                }
                "alias" => t.alias = Some(v.into_owned()),
                "api" => t.api = Some(v.into_owned()),
                "parent" => t.parent = split_list(&v),
                "objtypeenum" => t.objtypeenum = Some(v.into_owned()),
                "requires" => t.requires = Some(v.into_owned()),
                "bitvalues" => t.bitvalues = Some(v.into_owned()),
                "structextends" => t.structextends = split_list(&v),
                "returnedonly" => t.returnedonly = v == "true",
                "allowduplicate" => t.allowduplicate = v == "true",
                "deprecated" => t.deprecated = Some(v.into_owned()),
                _ => {}
            }
        }
        if !empty {
            loop {
                match self.child("type")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"member" => {
                            let m = self.member(&c, cempty, "member")?;
                            if is_vulkan_api(m.api.as_deref()) {
                                t.members.push(m);
                            }
                        }
                        b"name" => {
                            let s = self.text_of(&c, cempty, "name")?;
                            if t.name.is_empty() {
                                t.name = s;
                            }
                        }
                        b"type" => {
                            let s = self.text_of(&c, cempty, "type")?;
                            if t.base.is_none() {
                                t.base = Some(s);
                            }
                        }
                        b"comment" => self.skip(&c, cempty)?,
                        b"apientry" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "type")),
                    },
                }
            }
        }
        if t.name.is_empty() {
            return Err(self.err_at(pos, "<type> without a name"));
        }
        if t.category == TypeCategory::Handle && t.alias.is_none() {
            t.dispatchable = match t.base.as_deref() {
                Some("VK_DEFINE_HANDLE") => Some(true),
                Some("VK_DEFINE_NON_DISPATCHABLE_HANDLE") => Some(false),
                _ => None,
            };
        }
        if t.category == TypeCategory::Bitmask && t.bitvalues.is_none() {
            // old registries name the FlagBits enum with `requires`
            if let Some(r) = &t.requires {
                t.bitvalues = Some(r.clone());
            }
        }
        if is_vulkan_api(t.api.as_deref()) {
            self.reg.types.push(t);
        }
        Ok(())
    }

    /// The text content of a simple element such as `<name>`.
    fn text_of(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
        ctx: &str,
    ) -> Result<String, RegistryError> {
        let _ = e;
        let mut s = String::new();
        if empty {
            return Ok(s);
        }
        loop {
            match self.child(ctx)? {
                Ev::Close => return Ok(s),
                Ev::Text(t) => s.push_str(&self.unescape(&t)?),
                Ev::Open(c, _) => return Err(self.unexpected(&c, ctx)),
            }
        }
    }

    /// A `<member>`, `<param>` or `<proto>`.
    fn member(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
        ctx: &'static str,
    ) -> Result<Member, RegistryError> {
        let pos = self.start_pos();
        let mut m = Member::default();
        for (k, v) in self.attrs(e)? {
            match k {
                "optional" => m.optional = v.split(',').map(|x| x.trim() == "true").collect(),
                "len" => m.len = Some(v.into_owned()),
                "altlen" => m.altlen = Some(v.into_owned()),
                "values" => m.values = Some(v.into_owned()),
                "noautovalidity" => m.noautovalidity = v == "true",
                "limittype" => m.limittype = Some(v.into_owned()),
                "selector" => m.selector = Some(v.into_owned()),
                "selection" => m.selection = Some(v.into_owned()),
                "externsync" => m.externsync = Some(v.into_owned()),
                "objecttype" => m.objecttype = Some(v.into_owned()),
                "stride" => m.stride = Some(v.into_owned()),
                "validstructs" => m.validstructs = split_list(&v),
                "api" => m.api = Some(v.into_owned()),
                "deprecated" => m.deprecated = Some(v.into_owned()),
                _ => {}
            }
        }
        if empty {
            return Err(self.err_at(pos, format!("empty <{ctx}>")));
        }
        let mut decl = String::new();
        let mut after_name = String::new();
        let mut stage = 0u8; // 0 before <type>, 1 after type, 2 after name
        let mut between = String::new();
        loop {
            match self.child(ctx)? {
                Ev::Close => break,
                Ev::Text(t) => {
                    let t = self.unescape(&t)?;
                    decl.push_str(&t);
                    match stage {
                        1 => between.push_str(&t),
                        2 => after_name.push_str(&t),
                        _ => {}
                    }
                }
                Ev::Open(c, cempty) => match c.name().as_ref() {
                    b"type" => {
                        let s = self.text_of(&c, cempty, "type")?;
                        decl.push_str(&s);
                        m.type_name = s;
                        stage = 1;
                    }
                    b"name" => {
                        let s = self.text_of(&c, cempty, "name")?;
                        decl.push_str(&s);
                        m.name = s;
                        stage = 2;
                    }
                    b"enum" => {
                        let s = self.text_of(&c, cempty, "enum")?;
                        decl.push_str(&s);
                        if stage == 2 {
                            after_name.push_str(&s);
                        }
                    }
                    b"comment" => self.skip(&c, cempty)?,
                    _ => return Err(self.unexpected(&c, ctx)),
                },
            }
        }
        if m.name.is_empty() {
            return Err(self.err_at(pos, format!("<{ctx}> without a <name>")));
        }
        m.decl = collapse(&decl);
        m.is_const = m.decl.starts_with("const ");
        m.pointer_depth = between.bytes().filter(|&b| b == b'*').count() as u8;
        // arrays and bit-fields after the name
        let rest = after_name.trim();
        if let Some(bits) = rest.strip_prefix(':') {
            m.bitfield = bits.trim().parse().ok();
        } else {
            let mut r = rest;
            while let Some(open) = r.find('[') {
                let Some(close) = r[open..].find(']') else {
                    return Err(self.err_at(pos, format!("unclosed `[` in <{ctx}> {}", m.name)));
                };
                m.array.push(r[open + 1..open + close].trim().to_string());
                r = &r[open + close + 1..];
            }
        }
        Ok(m)
    }

    fn command(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut c = Command::default();
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => c.name = v.into_owned(),
                "alias" => c.alias = Some(v.into_owned()),
                "api" => c.api = Some(v.into_owned()),
                "successcodes" => c.successcodes = split_list(&v),
                "errorcodes" => c.errorcodes = split_list(&v),
                "queues" => c.queues = split_list(&v),
                "renderpass" => c.renderpass = Some(v.into_owned()),
                "videocoding" => c.videocoding = Some(v.into_owned()),
                "cmdbufferlevel" => c.cmdbufferlevel = split_list(&v),
                "tasks" => c.tasks = split_list(&v),
                _ => {}
            }
        }
        if !empty {
            loop {
                match self.child("command")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(ch, cempty) => match ch.name().as_ref() {
                        b"proto" => {
                            let p = self.member(&ch, cempty, "proto")?;
                            c.name = p.name;
                            c.return_type = p.type_name;
                        }
                        b"param" => {
                            let p = self.member(&ch, cempty, "param")?;
                            if is_vulkan_api(p.api.as_deref()) {
                                c.params.push(p);
                            }
                        }
                        b"implicitexternsyncparams" => {
                            if !cempty {
                                loop {
                                    match self.child("implicitexternsyncparams")? {
                                        Ev::Close => break,
                                        Ev::Text(_) => {}
                                        Ev::Open(p, pempty) if p.name().as_ref() == b"param" => {
                                            let s = self.text_of(&p, pempty, "param")?;
                                            c.implicit_externsync.push(collapse(&s));
                                        }
                                        Ev::Open(p, _) => {
                                            return Err(
                                                self.unexpected(&p, "implicitexternsyncparams")
                                            )
                                        }
                                    }
                                }
                            }
                        }
                        b"description" | b"comment" => self.skip(&ch, cempty)?,
                        _ => return Err(self.unexpected(&ch, "command")),
                    },
                }
            }
        }
        if c.name.is_empty() {
            return Err(self.err_at(pos, "<command> without a name"));
        }
        if is_vulkan_api(c.api.as_deref()) {
            self.reg.commands.push(c);
        }
        Ok(())
    }

    fn enums(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut g = EnumGroup {
            name: String::new(),
            kind: EnumKind::Constants,
            bitwidth: None,
            values: Vec::new(),
        };
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => g.name = v.into_owned(),
                "type" => {
                    g.kind = match &*v {
                        "enum" => EnumKind::Enum,
                        "bitmask" => EnumKind::Bitmask,
                        "constants" => EnumKind::Constants,
                        other => {
                            return Err(self.err_at(pos, format!("unknown enums type `{other}`")))
                        }
                    }
                }
                "bitwidth" => g.bitwidth = v.parse().ok(),
                _ => {}
            }
        }
        if g.name.is_empty() {
            return Err(self.err_at(pos, "<enums> without a name"));
        }
        let gi = self.reg.enum_groups.len();
        if !empty {
            loop {
                match self.child("enums")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"enum" => {
                            let vpos = self.start_pos();
                            let (v, _, _, api) = self.enum_attrs(&c, None)?;
                            self.skip(&c, cempty)?;
                            if !is_vulkan_api(api.as_deref()) {
                                continue;
                            }
                            let Some(v) = v else {
                                return Err(
                                    self.err_at(vpos, "<enum> without value, bitpos or alias")
                                );
                            };
                            if !self.values.contains_key(&v.name) {
                                self.values.insert(v.name.clone(), (gi, g.values.len()));
                                g.values.push(v);
                            }
                        }
                        b"unused" | b"comment" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "enums")),
                    },
                }
            }
        }
        self.groups.insert(g.name.clone(), gi);
        self.reg.enum_groups.push(g);
        Ok(())
    }

    /// Read an `<enum>`'s attributes. `ext_number` is the enclosing extension's number.
    /// Returns the value (None if it has neither value, bitpos, offset nor alias), the
    /// `extends` target, whether it used an offset, and its api attribute.
    #[allow(clippy::type_complexity)]
    fn enum_attrs(
        &self,
        e: &BytesStart<'a>,
        ext_number: Option<u32>,
    ) -> Result<(Option<EnumValue>, Option<String>, bool, Option<String>), RegistryError> {
        let pos = self.start_pos();
        let mut v = EnumValue {
            name: String::new(),
            value: None,
            bitpos: None,
            alias: None,
            raw: None,
            c_type: None,
            added_by: None,
            protect: None,
            deprecated: None,
        };
        let (mut extends, mut offset, mut extnumber, mut neg, mut api, mut has) =
            (None, None, None, false, None, false);
        for (k, val) in self.attrs(e)? {
            match k {
                "name" => v.name = val.into_owned(),
                "value" => {
                    has = true;
                    match parse_int_literal(&val) {
                        Some(x) if !val.contains('.') && !val.contains('"') => {
                            v.value = Some(x);
                            if val.contains('~') || val.contains('U') || val.contains('(') {
                                v.raw = Some(val.into_owned());
                            }
                        }
                        _ => v.raw = Some(val.into_owned()),
                    }
                }
                "bitpos" => {
                    has = true;
                    let b: u32 = val
                        .parse()
                        .map_err(|_| self.err_at(pos, format!("bad bitpos `{val}`")))?;
                    if b > 63 {
                        return Err(self.err_at(pos, format!("bitpos {b} out of range")));
                    }
                    v.bitpos = Some(b);
                    v.value = Some(1i64 << b);
                }
                "alias" => {
                    has = true;
                    v.alias = Some(val.into_owned())
                }
                "offset" => {
                    has = true;
                    offset = Some(
                        val.parse::<i64>()
                            .map_err(|_| self.err_at(pos, format!("bad offset `{val}`")))?,
                    )
                }
                "extnumber" => {
                    extnumber = Some(
                        val.parse::<i64>()
                            .map_err(|_| self.err_at(pos, format!("bad extnumber `{val}`")))?,
                    )
                }
                "dir" => neg = val == "-",
                "extends" => extends = Some(val.into_owned()),
                "type" => v.c_type = Some(val.into_owned()),
                "api" => api = Some(val.into_owned()),
                "protect" => v.protect = Some(val.into_owned()),
                "deprecated" => v.deprecated = Some(val.into_owned()),
                _ => {}
            }
        }
        if v.name.is_empty() {
            return Err(self.err_at(pos, "<enum> without a name"));
        }
        if let Some(off) = offset {
            let n = match extnumber.or(ext_number.map(i64::from)) {
                Some(n) => n,
                None => {
                    return Err(self.err_at(pos, format!("{}: offset without extnumber", v.name)))
                }
            };
            let x = 1_000_000_000 + (n - 1) * 1000 + off;
            v.value = Some(if neg { -x } else { x });
        } else if neg {
            if let Some(x) = v.value {
                v.value = Some(-x);
            }
        }
        Ok((has.then_some(v), extends, offset.is_some(), api))
    }

    fn feature(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut f = Feature {
            name: String::new(),
            number: String::new(),
            api: Vec::new(),
            depends: None,
            require: Vec::new(),
            remove: Vec::new(),
        };
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => f.name = v.into_owned(),
                "number" => f.number = v.into_owned(),
                "api" => f.api = split_list(&v),
                "depends" => f.depends = Some(self.condition(&v, pos)?),
                _ => {}
            }
        }
        if f.name.is_empty() {
            return Err(self.err_at(pos, "<feature> without a name"));
        }
        let keep = f.api.is_empty() || f.api.iter().any(|a| a == "vulkan");
        let name = f.name.clone();
        if !empty {
            loop {
                match self.child("feature")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"require" => {
                            if let Some(r) = self.require(&c, cempty, &name, None, keep)? {
                                f.require.push(r);
                            }
                        }
                        b"remove" => {
                            if let Some(r) = self.require(&c, cempty, &name, None, false)? {
                                f.remove.push(r);
                            }
                        }
                        b"comment" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "feature")),
                    },
                }
            }
        }
        if keep {
            self.reg.features.push(f);
        }
        Ok(())
    }

    fn condition(&self, s: &str, pos: usize) -> Result<Condition, RegistryError> {
        Condition::parse(s)
            .map_err(|(off, msg)| self.err_at(pos, format!("bad depends `{s}` (at {off}): {msg}")))
    }

    /// A `<require>`/`<remove>` block. Enum values it adds are queued when `apply` is set.
    /// Returns None if the block is for another API.
    fn require(
        &mut self,
        e: &BytesStart<'a>,
        empty: bool,
        owner: &str,
        ext_number: Option<u32>,
        apply: bool,
    ) -> Result<Option<Require>, RegistryError> {
        let pos = self.start_pos();
        let mut r = Require::default();
        let mut old_deps = Vec::new();
        for (k, v) in self.attrs(e)? {
            match k {
                "depends" => r.depends = Some(self.condition(&v, pos)?),
                "api" => r.api = Some(v.into_owned()),
                "comment" => r.comment = Some(v.into_owned()),
                "extension" | "feature" => old_deps.push(v.into_owned()),
                _ => {}
            }
        }
        if r.depends.is_none() && !old_deps.is_empty() {
            let joined = old_deps.join("+");
            r.depends = Some(self.condition(&joined, pos)?);
        }
        let keep = is_vulkan_api(r.api.as_deref());
        if !empty {
            loop {
                match self.child("require")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => {
                        let cpos = self.start_pos();
                        match c.name().as_ref() {
                            b"type" | b"command" => {
                                let name = self
                                    .attrs(&c)?
                                    .into_iter()
                                    .find(|(k, _)| *k == "name")
                                    .map(|(_, v)| v.into_owned());
                                let is_type = c.name().as_ref() == b"type";
                                self.skip(&c, cempty)?;
                                let Some(name) = name else {
                                    return Err(self.err_at(cpos, "reference without a name"));
                                };
                                if is_type {
                                    r.types.push(name);
                                } else {
                                    r.commands.push(name);
                                }
                            }
                            b"enum" => {
                                let (v, extends, _, api) = self.enum_attrs(&c, ext_number)?;
                                self.skip(&c, cempty)?;
                                if !is_vulkan_api(api.as_deref()) {
                                    continue;
                                }
                                let name = match &v {
                                    Some(v) => v.name.clone(),
                                    None => self
                                        .attrs(&c)
                                        .ok()
                                        .and_then(|a| {
                                            a.into_iter()
                                                .find(|(k, _)| *k == "name")
                                                .map(|(_, v)| v.into_owned())
                                        })
                                        .unwrap_or_default(),
                                };
                                r.enums.push(name);
                                if let (true, true, Some(mut v)) = (apply, keep, v) {
                                    v.added_by = Some(owner.to_string());
                                    let target = extends.unwrap_or_default();
                                    self.pending_ext.push((
                                        target,
                                        PendingValue {
                                            value: v,
                                            offset_pos: cpos,
                                        },
                                    ));
                                }
                            }
                            b"feature" => {
                                let a = self.attrs(&c)?;
                                self.skip(&c, cempty)?;
                                let get = |k: &str| {
                                    a.iter()
                                        .find(|(kk, _)| *kk == k)
                                        .map(|(_, v)| v.to_string())
                                        .unwrap_or_default()
                                };
                                r.features.push(FeatureRef {
                                    name: get("name"),
                                    structure: get("struct"),
                                });
                            }
                            b"comment" => self.skip(&c, cempty)?,
                            _ => return Err(self.unexpected(&c, "require")),
                        }
                    }
                }
            }
        }
        Ok(keep.then_some(r))
    }

    fn extension(&mut self, e: &BytesStart<'a>, empty: bool) -> Result<(), RegistryError> {
        let pos = self.start_pos();
        let mut x = Extension {
            name: String::new(),
            number: 0,
            ext_type: None,
            supported: Vec::new(),
            depends: None,
            promotedto: None,
            deprecatedby: None,
            obsoletedby: None,
            platform: None,
            provisional: false,
            specialuse: Vec::new(),
            ratified: Vec::new(),
            author: None,
            contact: None,
            require: Vec::new(),
            remove: Vec::new(),
        };
        let mut requires = None;
        for (k, v) in self.attrs(e)? {
            match k {
                "name" => x.name = v.into_owned(),
                "number" => {
                    x.number = v
                        .parse()
                        .map_err(|_| self.err_at(pos, format!("bad extension number `{v}`")))?
                }
                "type" => x.ext_type = Some(v.into_owned()),
                "supported" => x.supported = split_list(&v),
                "depends" => x.depends = Some(self.condition(&v, pos)?),
                "requires" => requires = Some(v.into_owned()),
                "promotedto" => x.promotedto = Some(v.into_owned()),
                "deprecatedby" => x.deprecatedby = Some(v.into_owned()),
                "obsoletedby" => x.obsoletedby = Some(v.into_owned()),
                "platform" => x.platform = Some(v.into_owned()),
                "provisional" => x.provisional = v == "true",
                "specialuse" => x.specialuse = split_list(&v),
                "ratified" => x.ratified = split_list(&v),
                "author" => x.author = Some(v.into_owned()),
                "contact" => x.contact = Some(v.into_owned()),
                _ => {}
            }
        }
        if x.name.is_empty() {
            return Err(self.err_at(pos, "<extension> without a name"));
        }
        if x.depends.is_none() {
            if let Some(req) = requires {
                // old registries: a comma-separated list of required extensions (all needed)
                x.depends = Some(self.condition(&req.replace(',', "+"), pos)?);
            }
        }
        let apply = x.is_vulkan();
        let name = x.name.clone();
        if !empty {
            loop {
                match self.child("extension")? {
                    Ev::Close => break,
                    Ev::Text(_) => {}
                    Ev::Open(c, cempty) => match c.name().as_ref() {
                        b"require" => {
                            if let Some(r) =
                                self.require(&c, cempty, &name, Some(x.number), apply)?
                            {
                                x.require.push(r);
                            }
                        }
                        b"remove" => {
                            if let Some(r) =
                                self.require(&c, cempty, &name, Some(x.number), false)?
                            {
                                x.remove.push(r);
                            }
                        }
                        b"comment" => self.skip(&c, cempty)?,
                        _ => return Err(self.unexpected(&c, "extension")),
                    },
                }
            }
        }
        self.reg.extensions.push(x);
        Ok(())
    }

    fn apply_pending(&mut self) -> Result<(), RegistryError> {
        for (target, pv) in std::mem::take(&mut self.pending_ext) {
            if self.values.contains_key(&pv.value.name) {
                continue;
            }
            if target.is_empty() {
                let idx = self.reg.ext_constants.len();
                self.values.insert(pv.value.name.clone(), (usize::MAX, idx));
                self.reg.ext_constants.push(pv.value);
                continue;
            }
            let Some(&gi) = self.groups.get(&target) else {
                return Err(self.err_at(
                    pv.offset_pos,
                    format!("{} extends unknown enum {}", pv.value.name, target),
                ));
            };
            let g = &mut self.reg.enum_groups[gi];
            self.values
                .insert(pv.value.name.clone(), (gi, g.values.len()));
            g.values.push(pv.value);
        }
        Ok(())
    }

    fn resolve_aliases(&mut self) {
        let lookup = |reg: &Registry,
                      values: &FastMap<String, (usize, usize)>,
                      name: &str|
         -> Option<(usize, usize)> {
            let _ = reg;
            values.get(name).copied()
        };
        let mut fixes = Vec::new();
        fn get(reg: &Registry, (g, v): (usize, usize)) -> &EnumValue {
            if g == usize::MAX {
                &reg.ext_constants[v]
            } else {
                &reg.enum_groups[g].values[v]
            }
        }
        for (name, &loc) in &self.values {
            let ev = get(&self.reg, loc);
            if ev.value.is_some() || ev.alias.is_none() {
                continue;
            }
            let mut cur = ev.alias.clone();
            let mut found = None;
            for _ in 0..8 {
                let Some(a) = cur else { break };
                let Some(l) = lookup(&self.reg, &self.values, &a) else {
                    break;
                };
                let t = get(&self.reg, l);
                if t.value.is_some() || t.raw.is_some() {
                    found = Some((t.value, t.raw.clone(), t.bitpos));
                    break;
                }
                cur = t.alias.clone();
            }
            if let Some(f) = found {
                fixes.push((name.clone(), loc, f));
            }
        }
        for (_, (g, v), (value, raw, bitpos)) in fixes {
            let ev = if g == usize::MAX {
                &mut self.reg.ext_constants[v]
            } else {
                &mut self.reg.enum_groups[g].values[v]
            };
            ev.value = value;
            if ev.raw.is_none() {
                ev.raw = raw;
            }
            if ev.bitpos.is_none() {
                ev.bitpos = bitpos;
            }
        }
    }
}

fn collapse(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for w in s.split_whitespace() {
        if !out.is_empty() {
            out.push(' ');
        }
        out.push_str(w);
    }
    out
}

fn intern(k: &[u8]) -> &'static str {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn int_literals() {
        assert_eq!(parse_int_literal("0x400"), Some(0x400));
        assert_eq!(parse_int_literal("(~0U)"), Some(0xFFFF_FFFF));
        assert_eq!(parse_int_literal("(~1U)"), Some(0xFFFF_FFFE));
        assert_eq!(parse_int_literal("(~0ULL)"), Some(-1));
        assert_eq!(parse_int_literal("-1"), Some(-1));
        assert_eq!(parse_int_literal("1000.0F"), None);
    }
}
