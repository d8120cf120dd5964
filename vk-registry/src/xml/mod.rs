//! vk.xml read with quick-xml (borrowed events over the text in memory) into a typed,
//! indexed, deterministic [`Registry`]: types, enums with every value (extension values
//! computed from offset/extnumber/dir), commands, features and extensions.
//!
//! Elements whose `api` attribute does not include `vulkan` are dropped. Sections that are not
//! modelled (platforms, tags, formats, SPIR-V tables, sync, video codecs) are skipped as a
//! whole; any other unexpected element is a located error.

mod enums;
mod parse;
mod types;

pub use parse::parse_int_literal;

use crate::error::{read_to_string, RegistryError};
use crate::vuid::Condition;
use parse::Parser;
use serde::{Deserialize, Serialize};
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
        // past i64: no value, never an overflow
        assert_eq!(parse_int_literal("--9223372036854775808"), None);
        assert_eq!(parse_int_literal("9223372036854775808"), None);
    }

    #[test]
    fn extension_enum_values_out_of_range_are_located_errors() {
        let doc = |attrs: &str| {
            format!(
                "<registry><enums name=\"VkResult\" type=\"enum\"/>\n<extensions>\n<extension name=\"VK_KHR_x\" number=\"1\" supported=\"vulkan\">\n\
                 <require>\n<enum {attrs} extends=\"VkResult\" name=\"VK_X\"/>\n</require>\n</extension>\n\
                 </extensions>\n</registry>\n"
            )
        };
        let ok = Registry::parse(&doc("offset=\"3\" dir=\"-\"")).unwrap();
        assert_eq!(ok.enum_value("VK_X"), Some(-1_000_000_003));
        for attrs in [
            "offset=\"9223372036854775807\"",
            "offset=\"0\" extnumber=\"9223372036854775807\"",
            "offset=\"0\" extnumber=\"-9223372036854775808\"",
            "value=\"(~9223372036854775807LL)\" dir=\"-\"",
        ] {
            let e = Registry::parse(&doc(attrs)).unwrap_err();
            assert_eq!(
                e.location(),
                Some(&crate::error::Location::LineCol { line: 5, column: 1 }),
                "{attrs}: {e}"
            );
            assert!(e.to_string().contains("VK_X"), "{attrs}: {e}");
        }
    }
}
