//! The errors of a case itself, found after it is read: a name that resolves to nothing (a buffer, an
//! acceleration structure), a shader group the pipeline lacks, two buffers of one name. Such a case
//! means nothing to a driver or a rule — it is neither valid nor invalid — so it is refused with the
//! YAML path of what is wrong (and, through [`crate::locate`], its line and column), never run and
//! never blamed on the driver.
//!
//! Deliberately dangling references that rules judge are not errors of the case: they are the invalid
//! states the rules describe — a descriptor naming a destroyed image, a raw address no buffer holds, an
//! NV table's `VkBuffer` handle naming no buffer (not a valid handle). A device *address* is a buffer
//! plus an offset, and names a buffer of the world or means nothing.

use crate::case::Case;
use serde_yaml::Value;
use std::collections::BTreeSet;

/// One error of a case: where it stands (a YAML path) and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Flaw {
    /// `world.buffers[0].contents[1].handles[0]`.
    pub at: String,
    pub problem: String,
}

/// Every error of the case, in the order of the file.
pub fn flaws(case: &Case) -> Vec<Flaw> {
    let Ok(doc) = serde_yaml::to_value(case) else {
        return vec![];
    };
    let world = doc.get("world");
    let names = |list: &str| -> Vec<(usize, String)> {
        world
            .and_then(|w| w.get(list))
            .and_then(Value::as_sequence)
            .map(|items| {
                items
                    .iter()
                    .enumerate()
                    .filter_map(|(i, v)| Some((i, v.get("name")?.as_str()?.to_string())))
                    .collect()
            })
            .unwrap_or_default()
    };
    let buffers = names("buffers");
    let structures = names("structures");
    let mut out = Vec::new();
    for (list, named) in [("buffers", &buffers), ("structures", &structures)] {
        let mut seen = BTreeSet::new();
        for (i, n) in named.iter() {
            if !seen.insert(n.as_str()) {
                out.push(Flaw {
                    at: format!("world.{list}[{i}].name"),
                    problem: format!("a second {} named `{n}`", &list[..list.len() - 1]),
                });
            }
        }
    }
    let groups = case
        .as_trace()
        .map(|t| t.world.pipeline.as_ref().map(|p| p.groups.len()));
    let scope = Scope {
        buffers: buffers.into_iter().map(|(_, n)| n).collect(),
        structures: structures.into_iter().map(|(_, n)| n).collect(),
        groups,
    };
    for key in ["world", "call"] {
        if let Some(v) = doc.get(key) {
            scope.walk(v, key.to_string(), &mut out);
        }
    }
    out
}

/// The names a case's references must resolve to.
struct Scope {
    buffers: BTreeSet<String>,
    structures: BTreeSet<String>,
    /// For a trace case: the bound pipeline's group count (None: the world has no pipeline).
    groups: Option<Option<usize>>,
}

impl Scope {
    fn walk(&self, v: &Value, at: String, out: &mut Vec<Flaw>) {
        match v {
            Value::Mapping(m) => {
                let is_address = m.len() == 2
                    && m.get("offset").is_some()
                    && m.get("buffer").is_some_and(Value::is_string);
                let is_structure = at.starts_with("world.structures[") && at.ends_with(']');
                for (k, child) in m {
                    let Some(key) = k.as_str() else { continue };
                    let here = format!("{at}.{key}");
                    // Descriptors may name destroyed objects on purpose (rules judge them).
                    if here == "world.resources" {
                        continue;
                    }
                    let names_buffer = key == "buffer" && (is_address || is_structure);
                    self.field(key, names_buffer, child, &here, out);
                    self.walk(child, here, out);
                }
            }
            Value::Sequence(items) => {
                for (i, child) in items.iter().enumerate() {
                    self.walk(child, format!("{at}[{i}]"), out);
                }
            }
            Value::Tagged(t) => {
                self.tagged(&t.tag.to_string(), &t.value, &at, out);
                self.walk(&t.value, at, out);
            }
            _ => {}
        }
    }

    /// A named reference held in a field: the `buffer` of an address or of a build's structure, the
    /// `src`/`dst` of a build info.
    fn field(&self, key: &str, names_buffer: bool, v: &Value, at: &str, out: &mut Vec<Flaw>) {
        let Some(name) = v.as_str() else { return };
        match key {
            "buffer" if names_buffer && !self.buffers.contains(name) => out.push(Flaw {
                at: at.to_string(),
                problem: format!("names buffer `{name}`, which the world lacks"),
            }),
            "src" | "dst" if at.starts_with("call.infos[") && !self.structures.contains(name) => {
                out.push(Flaw {
                    at: at.to_string(),
                    problem: format!(
                        "names acceleration structure `{name}`, which the world lacks"
                    ),
                })
            }
            _ => {}
        }
    }

    /// A tagged reference: `!group N` of a shader record, `!structure NAME` of an instance record.
    fn tagged(&self, tag: &str, v: &Value, at: &str, out: &mut Vec<Flaw>) {
        match tag.trim_start_matches('!') {
            "group" => {
                let (Some(groups), Some(n)) = (self.groups, v.as_u64()) else {
                    return;
                };
                match groups {
                    None => out.push(Flaw {
                        at: at.to_string(),
                        problem: format!("the handle of group {n}, but the world has no pipeline"),
                    }),
                    Some(len) if n >= len as u64 => out.push(Flaw {
                        at: at.to_string(),
                        problem: format!(
                            "the handle of group {n}, but the pipeline has {len} group(s) (0 to {})",
                            len.saturating_sub(1)
                        ),
                    }),
                    Some(_) => {}
                }
            }
            "structure" => {
                if let Some(name) = v.as_str() {
                    if !self.structures.contains(name) {
                        out.push(Flaw {
                            at: at.to_string(),
                            problem: format!(
                                "references acceleration structure `{name}`, which the world lacks"
                            ),
                        });
                    }
                }
            }
            _ => {}
        }
    }
}
