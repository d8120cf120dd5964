//! The streamed walk held to the value walk: on every repository case, mutated to carry each kind of
//! flaw, and on random serde shapes; and the order of its flaws.

use super::*;
use serde::ser::{Serialize, SerializeMap, SerializeStructVariant, SerializeTupleVariant};

/// The walk over the whole case document, as the reference for the parts it is given.
fn flaws_of_whole_document(case: &Case) -> Vec<Flaw> {
    let doc = serde_yaml::to_value(case).expect("a case serialises");
    walk_of_value(&doc, groups(case))
}

/// The value walk of a document's `world` and `call`, with the names the document's world holds.
fn walk_of_value(doc: &Value, groups: Option<Option<usize>>) -> Vec<Flaw> {
    let world = doc.get("world");
    let scope = Scope {
        buffers: names(world, "buffers")
            .into_iter()
            .map(|(_, n)| n)
            .collect(),
        structures: names(world, "structures")
            .into_iter()
            .map(|(_, n)| n)
            .collect(),
        groups,
    };
    let mut out = Vec::new();
    for key in ["world", "call"] {
        if let Some(v) = doc.get(key) {
            scope.walk(v, &mut key.to_string(), &mut out);
        }
    }
    out
}

/// The flaws of the walk alone: without the duplicate names and the NV pipeline's dynamic stack
/// size, which are found from the lists and the pipeline, not by the walk.
fn of_the_walk(flaws: &[Flaw]) -> Vec<Flaw> {
    flaws
        .iter()
        .filter(|f| {
            !f.problem.starts_with("a second ") && f.at != "world.pipeline.dynamic_stack_size"
        })
        .cloned()
        .collect()
}

#[test]
fn the_referencing_parts_find_what_the_whole_document_finds() {
    let files = crate::test_cases::repository_case_files();
    let mut compared = 0;
    let mut with_launch = 0;
    for f in files {
        let text = std::fs::read_to_string(&f).expect("a case file reads");
        let Ok(mut case) = Case::from_yaml(&f.display().to_string(), &text) else {
            continue;
        };
        let dangling = |case: &mut Case| {
            if let Some(b) = case
                .as_trace_mut()
                .and_then(|t| t.world.buffers.first_mut())
            {
                b.name = format!("{}-renamed", b.name);
            }
        };
        for planted in [false, true] {
            if planted {
                dangling(&mut case);
            }
            assert_eq!(
                flaws(&case),
                flaws_of_whole_document(&case),
                "{} (a buffer renamed: {planted})",
                f.display()
            );
        }
        compared += 1;
        with_launch += case
            .as_trace()
            .is_some_and(|t| !t.world.launch.rays.is_empty() || t.world.launch.camera.is_some())
            as usize;
    }
    assert!(
        compared > 50 && with_launch > 5,
        "{compared} cases, {with_launch} with a launch"
    );
}

#[test]
fn a_dangling_address_is_found_in_a_trace_world() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/hand/trace-indirect-records-32.yaml");
    let text = std::fs::read_to_string(&root).expect("the hand case reads");
    let mut case = Case::from_yaml("hand", &text).expect("the hand case parses");
    assert!(flaws(&case).is_empty());
    let t = case.as_trace_mut().expect("a trace case");
    let first = t.world.buffers[0].name.clone();
    t.world.buffers[0].name = "elsewhere".into();
    let found = flaws(&case);
    assert!(
        found
            .iter()
            .any(|f| f.problem.contains(&format!("`{first}`"))),
        "{found:?}"
    );
}

#[test]
fn a_scope_a_command_buffer_cannot_be_inside_is_refused_with_its_place() {
    use crate::world::{CommandBufferLevel as V, CommandBufferLifecycle as L};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../cases");
    for file in [
        "hand/trace-indirect-records-32.yaml",
        "build/state-renderpass.yaml",
    ] {
        let text = std::fs::read_to_string(dir.join(file)).expect("the case reads");
        let case = Case::from_yaml(file, &text).expect("the case parses");
        assert!(flaws(&case).is_empty(), "{file}");
        let set =
            |c: &mut Case, f: &dyn Fn(&mut crate::world::CommandBufferState)| match &mut c.body {
                Body::Trace(t) => f(&mut t.world.command_buffer),
                Body::Accel(a) => f(&mut a.world.command_buffer),
            };
        for lifecycle in [L::Recording, L::Initial, L::Executable, L::Invalid] {
            for level in [V::Primary, V::Secondary] {
                for field in [
                    "in_render_pass",
                    "in_video_coding",
                    "between_suspended_render_passes",
                ] {
                    let mut c = case.clone();
                    set(&mut c, &|cb| {
                        cb.lifecycle = lifecycle;
                        cb.level = level;
                        cb.in_render_pass = field == "in_render_pass";
                        cb.in_video_coding = field == "in_video_coding";
                        cb.between_suspended_render_passes =
                            field == "between_suspended_render_passes";
                    });
                    let found = flaws(&c);
                    // Never begun: nothing; ended as a primary: outside render passes and video
                    // coding scopes. A secondary's inherited render pass and an invalid command
                    // buffer's scopes are states a case may state.
                    let refused = lifecycle == L::Initial
                        || (lifecycle == L::Executable
                            && level == V::Primary
                            && field != "between_suspended_render_passes");
                    if !refused {
                        assert!(
                            found.is_empty(),
                            "{file} {lifecycle:?} {level:?} {field}: {found:?}"
                        );
                        continue;
                    }
                    assert_eq!(
                        found.len(),
                        1,
                        "{file} {lifecycle:?} {level:?} {field}: {found:?}"
                    );
                    assert_eq!(found[0].at, format!("world.command_buffer.{field}"));
                    // Read from its YAML, the case is refused at the field's line.
                    let yaml = c.to_yaml();
                    let err = Case::read(file, &yaml).expect_err("refused");
                    let line = yaml
                        .lines()
                        .position(|l| l.trim_start().starts_with(&format!("{field}:")))
                        .expect("the field is written")
                        + 1;
                    assert!(
                        err.to_string().starts_with(&format!("{file}:{line}:")),
                        "{err} (field on line {line})"
                    );
                }
            }
        }
    }
}

/// Applies `plant` to every value of `v`, depth first, with each value's path; the number of
/// values it changed.
fn plant_everywhere(
    v: &mut Value,
    at: &mut String,
    plant: &mut dyn FnMut(&mut Value, &str) -> bool,
) -> usize {
    let len = at.len();
    let mut planted = plant(v, at) as usize;
    match v {
        Value::Mapping(m) => {
            for (k, child) in m.iter_mut() {
                if let Some(k) = k.as_str() {
                    if len > 0 {
                        at.push('.');
                    }
                    at.push_str(k);
                    planted += plant_everywhere(child, at, plant);
                    at.truncate(len);
                }
            }
        }
        Value::Sequence(items) => {
            for (i, child) in items.iter_mut().enumerate() {
                at.push_str(&format!("[{i}]"));
                planted += plant_everywhere(child, at, plant);
                at.truncate(len);
            }
        }
        Value::Tagged(t) => planted += plant_everywhere(&mut t.value, at, plant),
        _ => {}
    }
    planted
}

/// The world's `buffers` or `structures` of a case's YAML value.
fn list<'v>(doc: &'v mut Value, list: &str) -> Option<&'v mut Vec<Value>> {
    doc.get_mut("world")?.get_mut(list)?.as_sequence_mut()
}

/// Plants an error in a case's YAML value; how many places it changed.
type Plant = fn(&mut Value) -> usize;

/// The errors that can be planted in a case's YAML value, each with its name and whether the
/// case then certainly has a flaw (a renamed buffer or structure may be named by nothing).
const PLANTS: &[(&str, bool, Plant)] = &[
    ("a buffer renamed", false, |doc| {
        let Some(first) = list(doc, "buffers").and_then(|b| b.first_mut()) else {
            return 0;
        };
        first["name"] = Value::String("renamed".into());
        1
    }),
    ("a second buffer of one name", true, |doc| {
        let Some(buffers) = list(doc, "buffers").filter(|b| !b.is_empty()) else {
            return 0;
        };
        let name = buffers[0]["name"].clone();
        let mut second = buffers[buffers.len() / 2].clone();
        second["name"] = name;
        buffers.push(second);
        1
    }),
    ("a structure renamed", false, |doc| {
        let Some(first) = list(doc, "structures").and_then(|s| s.first_mut()) else {
            return 0;
        };
        first["name"] = Value::String("renamed".into());
        1
    }),
    ("every other group past the pipeline's", true, |doc| {
        let mut k = 0u64;
        plant_everywhere(doc, &mut String::new(), &mut |v, _| match v {
            Value::Tagged(t) if t.tag == "group" => {
                k += 1;
                if k % 2 == 0 {
                    return false;
                }
                t.value = Value::Number((1000 + k).into());
                true
            }
            _ => false,
        })
    }),
    ("every structure reference dangling", true, |doc| {
        plant_everywhere(doc, &mut String::new(), &mut |v, _| match v {
            Value::Tagged(t) if t.tag == "structure" && t.value.is_string() => {
                t.value = Value::String("nowhere".into());
                true
            }
            _ => false,
        })
    }),
    ("every other address dangling", true, |doc| {
        let mut k = 0;
        plant_everywhere(doc, &mut String::new(), &mut |v, _| {
            let Value::Mapping(m) = v else { return false };
            if m.len() != 2
                || !m.contains_key("offset")
                || !m.get("buffer").is_some_and(Value::is_string)
            {
                return false;
            }
            k += 1;
            if k % 2 == 0 {
                return false;
            }
            m["buffer"] = Value::String("nowhere".into());
            true
        })
    }),
    ("every structure's buffer dangling", true, |doc| {
        list(doc, "structures").map_or(0, |s| {
            s.iter_mut()
                .map(|s| s["buffer"] = Value::String("nowhere".into()))
                .count()
        })
    }),
    (
        "every build's source and destination dangling",
        true,
        |doc| {
            plant_everywhere(doc, &mut String::new(), &mut |v, at| {
                let Value::Mapping(m) = v else { return false };
                if !at.starts_with("call.infos[") {
                    return false;
                }
                let mut planted = false;
                for key in ["src", "dst"] {
                    if m.get(key).is_some_and(Value::is_string) {
                        m[key] = Value::String(format!("no-{key}"));
                        planted = true;
                    }
                }
                planted
            })
        },
    ),
];

#[test]
fn the_streamed_walk_finds_what_the_value_walk_finds() {
    let mut cases = Vec::new();
    for f in crate::test_cases::repository_case_files() {
        let text = std::fs::read_to_string(&f).expect("a case file reads");
        if let Ok(case) = Case::from_yaml("c", &text) {
            cases.push((f.display().to_string(), case));
        }
    }
    assert!(cases.len() > 100, "only {} cases read", cases.len());
    let mut planted = vec![0; PLANTS.len() + 1];
    let mut compared = 0;
    for (path, case) in &cases {
        let doc = serde_yaml::to_value(case).expect("a case serialises");
        // The case as it is, each error planted alone, and all of them at once.
        let mut variants = vec![(String::from("as it is"), case.clone(), false)];
        let mut all = doc.clone();
        let (mut any, mut certain) = (false, false);
        for (p, &(what, flaws, plant)) in PLANTS.iter().enumerate() {
            let mut v = doc.clone();
            let n = plant(&mut v);
            let in_all = plant(&mut all) > 0;
            any |= in_all;
            certain |= in_all && flaws;
            if n == 0 {
                continue;
            }
            let Ok(c) = serde_yaml::from_value::<Case>(v) else {
                continue;
            };
            planted[p] += 1;
            variants.push((what.to_string(), c, flaws));
        }
        if any {
            if let Ok(c) = serde_yaml::from_value::<Case>(all) {
                planted[PLANTS.len()] += 1;
                variants.push(("all of them".into(), c, certain));
            }
        }
        for (what, c, flawed) in variants {
            let streamed = streamed(&c)
                .unwrap_or_else(|e| panic!("{path} ({what}): the streamed walk gave up: {e}"));
            assert_eq!(streamed, flaws_of_value(&c), "{path} ({what})");
            assert_eq!(
                of_the_walk(&streamed),
                flaws_of_whole_document(&c),
                "{path} ({what})"
            );
            assert_eq!(flaws(&c), streamed, "{path} ({what})");
            assert!(!flawed || !streamed.is_empty(), "{path} ({what})");
            compared += 1;
        }
    }
    for (p, n) in planted.iter().enumerate() {
        let what = PLANTS.get(p).map_or("all of them", |&(w, ..)| w);
        assert!(*n >= 10, "`{what}` planted in only {n} cases");
    }
    assert!(compared > 1_000, "{compared} cases compared");
}

#[test]
fn a_streamed_flaw_of_a_field_comes_before_those_inside_its_value() {
    // An address whose buffer is itself a dangling structure reference, then a dangling group:
    // the address's flaw, known only at the mapping's end, goes before both.
    let doc = Tree::Map(vec![
        (Tree::Str("world"), Tree::Map(vec![])),
        (
            Tree::Str("call"),
            Tree::Map(vec![(
                Tree::Str("raygen"),
                Tree::Map(vec![
                    (
                        Tree::Str("buffer"),
                        Tree::Newtype("structure", Box::new(Tree::Str("s"))),
                    ),
                    (
                        Tree::Str("offset"),
                        Tree::Newtype("group", Box::new(Tree::Int(7))),
                    ),
                ]),
            )]),
        ),
    ]);
    let scope = Scope {
        buffers: BTreeSet::new(),
        structures: BTreeSet::new(),
        groups: Some(Some(2)),
    };
    let found = Stream::walk(&doc, &scope, [&[], &[]], Vec::new()).expect("streamed");
    let problems: Vec<&str> = found.iter().map(|f| f.problem.as_str()).collect();
    assert_eq!(
        problems,
        [
            "names buffer `s`, which the world lacks",
            "references acceleration structure `s`, which the world lacks",
            "the handle of group 7, but the pipeline has 2 group(s) (0 to 1)",
        ]
    );
    assert!(found.iter().take(2).all(|f| f.at == "call.raygen.buffer"));
    let value = serde_yaml::to_value(&doc).expect("a value");
    assert_eq!(found, walk_of_value(&value, Some(Some(2))));
}

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
}

/// Any shape serde can hand a serializer, for holding the streamed walk to the value walk on
/// layouts no case has.
#[derive(Debug, Clone)]
enum Tree {
    Str(&'static str),
    Int(i64),
    Big(i128),
    Float(f64),
    Bool(bool),
    Null,
    Char(char),
    Bytes(&'static [u8]),
    Seq(Vec<Tree>),
    Map(Vec<(Tree, Tree)>),
    /// A map serialised without its length.
    Unsized(Vec<(Tree, Tree)>),
    Struct(Vec<(&'static str, Tree)>),
    Some(Box<Tree>),
    Unit(&'static str),
    Newtype(&'static str, Box<Tree>),
    StructVariant(&'static str, Vec<(&'static str, Tree)>),
    Tuple(&'static str, Vec<Tree>),
    /// serde_yaml's own tagged value, which serialises as a map of one entry keyed `!tag`.
    Tagged(&'static str, Box<Tree>),
}

impl Serialize for Tree {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Tree::Str(v) => s.serialize_str(v),
            Tree::Int(v) => s.serialize_i64(*v),
            Tree::Big(v) => s.serialize_i128(*v),
            Tree::Float(v) => s.serialize_f64(*v),
            Tree::Bool(v) => s.serialize_bool(*v),
            Tree::Null => s.serialize_none(),
            Tree::Char(v) => s.serialize_char(*v),
            Tree::Bytes(v) => s.serialize_bytes(v),
            Tree::Seq(v) => v.serialize(s),
            Tree::Map(entries) | Tree::Unsized(entries) => {
                let len = matches!(self, Tree::Map(_)).then_some(entries.len());
                let mut m = s.serialize_map(len)?;
                for (k, v) in entries {
                    m.serialize_entry(k, v)?;
                }
                m.end()
            }
            Tree::Struct(fields) => {
                use serde::ser::SerializeStruct;
                let mut m = s.serialize_struct("T", fields.len())?;
                for (k, v) in fields {
                    m.serialize_field(k, v)?;
                }
                m.end()
            }
            Tree::Some(v) => s.serialize_some(v),
            Tree::Unit(name) => s.serialize_unit_variant("T", 0, name),
            Tree::Newtype(name, v) => s.serialize_newtype_variant("T", 0, name, v),
            Tree::StructVariant(name, fields) => {
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
            Tree::Tagged(tag, v) => serde_yaml::value::TaggedValue {
                tag: serde_yaml::value::Tag::new(*tag),
                value: serde_yaml::to_value(v).map_err(serde::ser::Error::custom)?,
            }
            .serialize(s),
        }
    }
}

/// Keys the walk treats apart, and others; the last two are the world's lists of names.
const KEYS: &[&str] = &[
    "buffer",
    "offset",
    "src",
    "dst",
    "name",
    "infos",
    "resources",
    "call",
    "world",
    "x",
    "structures",
    "buffers",
];
const NAMES: &[&str] = &["a", "b", "c", "nowhere", ""];
const VARIANTS: &[&str] = &["group", "structure", "!group", "!!structure", "x"];

/// A variant's name: now and then the empty one, which `to_value` refuses.
fn variant(r: &mut Rng) -> &'static str {
    match r.below(40) {
        0 => "",
        _ => r.pick(VARIANTS),
    }
}

fn scalar(r: &mut Rng) -> Tree {
    match r.below(20) {
        0..=7 => Tree::Str(r.pick(NAMES)),
        8..=10 => Tree::Int(r.below(6) as i64 - 1),
        11 => Tree::Big(r.pick(&[-1, 3, i128::MAX, i128::MIN, u64::MAX as i128])),
        12 => Tree::Float(0.5),
        13 => Tree::Bool(true),
        14 => Tree::Null,
        15 => Tree::Char('a'),
        16 => Tree::Bytes(b"ab"),
        _ => Tree::Unit(r.pick(&["a", "b", "group", ""])),
    }
}

fn key(r: &mut Rng) -> Tree {
    match r.below(30) {
        0 => Tree::Int(1),
        1 => Tree::Char('x'),
        2 => Tree::Unit("buffer"),
        3 => Tree::Some(Box::new(Tree::Str("offset"))),
        4 => Tree::Newtype("x", Box::new(Tree::Str("buffer"))),
        _ => Tree::Str(r.pick(KEYS)),
    }
}

/// Up to three entries; now and then two of one key.
fn entries<K: std::fmt::Debug>(
    r: &mut Rng,
    depth: usize,
    key: impl Fn(&mut Rng) -> K,
) -> Vec<(K, Tree)> {
    let mut out: Vec<(K, Tree)> = Vec::new();
    for _ in 0..r.below(4) {
        let k = key(r);
        let twice = out
            .iter()
            .any(|(o, _)| format!("{o:?}") == format!("{k:?}"));
        if !twice || r.below(10) == 0 {
            out.push((k, tree(r, depth)));
        }
    }
    out
}

fn tree(r: &mut Rng, depth: usize) -> Tree {
    if depth == 0 || r.below(4) == 0 {
        return scalar(r);
    }
    let d = depth - 1;
    match r.below(17) {
        0..=1 => Tree::Seq((0..r.below(4)).map(|_| tree(r, d)).collect()),
        2..=3 => Tree::Map(entries(r, d, key)),
        4 => Tree::Unsized(entries(r, d, key)),
        5..=7 => Tree::Struct(entries(r, d, |r| r.pick(KEYS))),
        8 => Tree::Some(Box::new(tree(r, d))),
        9..=11 => Tree::Newtype(variant(r), Box::new(tree(r, d))),
        12 => Tree::StructVariant(variant(r), entries(r, d, |r| r.pick(KEYS))),
        13 => Tree::Tuple(variant(r), (0..r.below(3)).map(|_| tree(r, d)).collect()),
        14 if r.below(6) == 0 => Tree::Tagged(r.pick(VARIANTS), Box::new(tree(r, d))),
        _ => Tree::Struct(vec![
            ("buffer", Tree::Str(r.pick(NAMES))),
            ("offset", Tree::Int(0)),
        ]),
    }
}

/// A world of named buffers and structures, now and then with a flaw of its own form.
fn world(r: &mut Rng) -> Tree {
    let named = |r: &mut Rng| {
        let mut fields = vec![("name", Tree::Str(r.pick(NAMES)))];
        fields.extend(entries(r, 2, |r| r.pick(&KEYS[..4])));
        match r.below(60) {
            0 => Tree::Map(vec![(Tree::Str("name"), Tree::Str("a"))]),
            1 => Tree::Struct(vec![("size", Tree::Int(1))]),
            2 => Tree::Newtype("named", Box::new(Tree::Struct(fields))),
            _ => Tree::Struct(fields),
        }
    };
    let mut fields = Vec::new();
    for list in ["buffers", "structures"] {
        if r.below(5) > 0 {
            fields.push((list, Tree::Seq((0..r.below(4)).map(|_| named(r)).collect())));
        }
    }
    // Now and then a second list of one name (which the stream gives up on).
    let keys = if r.below(20) == 0 {
        KEYS
    } else {
        &KEYS[..KEYS.len() - 2]
    };
    fields.extend(entries(r, 3, |r| r.pick(keys)));
    if r.below(20) == 0 {
        fields.reverse();
    }
    Tree::Struct(fields)
}

#[test]
fn the_streamed_walk_reads_any_shape_as_the_value_walk_does() {
    let mut r = Rng(0x5851_f42d_4c95_7f2d);
    let (mut streamed, mut gave_up) = (0, 0);
    // How many flaws of each kind the streamed trees had.
    let mut kinds = [0; 5];
    for _ in 0..20_000 {
        let call = match r.below(2) {
            0 => tree(&mut r, 4),
            _ => Tree::Struct(vec![(
                "infos",
                Tree::Seq((0..r.below(3)).map(|_| tree(&mut r, 3)).collect()),
            )]),
        };
        let mut top = vec![
            (Tree::Str("world"), world(&mut r)),
            (Tree::Str("call"), call),
            (Tree::Str("name"), tree(&mut r, 2)),
        ];
        top.truncate(2 + r.below(2));
        if r.below(20) == 0 {
            top.swap(0, 1);
        }
        let top = match r.below(3) {
            0 => Tree::Unsized(top),
            _ => Tree::Map(top),
        };
        let groups = match r.below(3) {
            0 => None,
            1 => Some(None),
            _ => Some(Some(r.below(4))),
        };
        let Ok(doc) = serde_yaml::to_value(&top) else {
            // What `to_value` refuses, the stream refuses too (the fallback finds nothing).
            let scope = Scope {
                buffers: BTreeSet::new(),
                structures: BTreeSet::new(),
                groups,
            };
            assert!(Stream::walk(&top, &scope, [&[], &[]], Vec::new()).is_err());
            continue;
        };
        let world = doc.get("world");
        let lists = [names(world, "buffers"), names(world, "structures")];
        let named: Vec<Vec<&str>> = lists
            .iter()
            .map(|l| l.iter().map(|&(_, n)| n).collect())
            .collect();
        let scope = Scope {
            buffers: named[0].iter().copied().collect(),
            structures: named[1].iter().copied().collect(),
            groups,
        };
        match Stream::walk(&top, &scope, [&named[0], &named[1]], Vec::new()) {
            Ok(found) => {
                assert_eq!(found, walk_of_value(&doc, groups), "{top:#?}");
                streamed += 1;
                for f in &found {
                    let kind = [
                        "names buffer",
                        "names acceleration structure",
                        "references acceleration structure",
                        "the handle of group",
                    ]
                    .iter()
                    .position(|k| f.problem.starts_with(k));
                    kinds[kind.unwrap_or(4)] += 1;
                }
            }
            Err(_) => gave_up += 1,
        }
    }
    assert!(
        streamed >= 10_000,
        "streamed {streamed}, gave up on {gave_up}"
    );
    assert!(
        kinds[..4].iter().all(|&n| n >= 100),
        "flaws by kind: {kinds:?}"
    );
    assert_eq!(kinds[4], 0, "flaws of no kind the walk finds");
}

#[test]
fn the_stream_gives_up_on_names_other_than_the_case_holds() {
    let doc = Tree::Struct(vec![(
        "world",
        Tree::Struct(vec![(
            "buffers",
            Tree::Seq(vec![Tree::Struct(vec![("name", Tree::Str("a"))])]),
        )]),
    )]);
    let scope = |names: &[&'static str]| Scope {
        buffers: names.iter().copied().collect(),
        structures: BTreeSet::new(),
        groups: None,
    };
    let walk = |names: &[&'static str]| {
        Stream::walk(&doc, &scope(names), [names, &[]], Vec::new()).is_ok()
    };
    assert!(walk(&["a"]));
    assert!(!walk(&["b"]));
    assert!(!walk(&["a", "b"]));
    assert!(!walk(&[]));
}
