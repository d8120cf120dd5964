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

/// The parts of a trace case that can hold references, in the case's YAML form: its world without
/// the launch (scenes, rays and the camera hold geometry and indices, never a name — `Scene::undefined`
/// judges their indices) and without the resource state (descriptors may name destroyed objects on
/// purpose), and its call. A rendered scene's thousands of coordinates are never turned into YAML
/// values to be walked.
#[derive(serde::Serialize)]
struct TraceReferences<'a> {
    world: WorldReferences<'a>,
    call: CallReferences<'a>,
}

#[derive(serde::Serialize)]
struct WorldReferences<'a> {
    device: &'a crate::world::DeviceState,
    buffers: &'a [crate::world::Buffer],
    pipeline: &'a Option<crate::world::Pipeline>,
    command_buffer: &'a crate::world::CommandBufferState,
}

/// A trace call as the case's YAML writes it: the call's own fields, without the command's tag.
#[derive(serde::Serialize)]
#[serde(untagged)]
enum CallReferences<'a> {
    Indirect(&'a crate::call::TraceRaysIndirect),
    Direct(&'a crate::call::TraceRays),
    Nv(&'a crate::call::TraceRaysNv),
}

/// The case as a YAML value for the walk: every part that can hold a reference.
fn referencing_parts(case: &Case) -> Option<Value> {
    use crate::call::Call;
    let Some(t) = case.as_trace() else {
        return serde_yaml::to_value(case).ok();
    };
    // Destructured so that a field added to the world is a compile error here until it is placed.
    let crate::world::World {
        device,
        buffers,
        pipeline,
        command_buffer,
        launch: _,
        resources: _,
    } = &t.world;
    let call = match &t.call {
        Call::TraceRaysIndirect(c) => CallReferences::Indirect(c),
        Call::TraceRays(c) => CallReferences::Direct(c),
        Call::TraceRaysNv(c) => CallReferences::Nv(c),
    };
    serde_yaml::to_value(TraceReferences {
        world: WorldReferences {
            device,
            buffers,
            pipeline,
            command_buffer,
        },
        call,
    })
    .ok()
}

/// Every error of the case, in the order of the file.
pub fn flaws(case: &Case) -> Vec<Flaw> {
    let Some(doc) = referencing_parts(case) else {
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
    // vkCreateRayTracingPipelinesNV takes no dynamic states: such a pipeline cannot exist.
    if let Some(p) = case.as_trace().and_then(|t| t.world.pipeline.as_ref()) {
        if p.api == crate::world::PipelineApi::Nv && p.dynamic_stack_size {
            out.push(Flaw {
                at: "world.pipeline.dynamic_stack_size".into(),
                problem: "an NV pipeline (vkCreateRayTracingPipelinesNV) has no dynamic states, so no dynamic stack size".into(),
            });
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
            scope.walk(v, &mut key.to_string(), &mut out);
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
    /// Walks `v`, whose YAML path is `at` (a buffer extended and cut back as the walk goes down and
    /// up, so a path is only written out for a flaw).
    fn walk(&self, v: &Value, at: &mut String, out: &mut Vec<Flaw>) {
        use std::fmt::Write;
        let len = at.len();
        match v {
            Value::Mapping(m) => {
                let is_address = m.len() == 2
                    && m.get("offset").is_some()
                    && m.get("buffer").is_some_and(Value::is_string);
                let is_structure = at.starts_with("world.structures[") && at.ends_with(']');
                for (k, child) in m {
                    let Some(key) = k.as_str() else { continue };
                    at.push('.');
                    at.push_str(key);
                    // Descriptors may name destroyed objects on purpose (rules judge them).
                    if at != "world.resources" {
                        let names_buffer = key == "buffer" && (is_address || is_structure);
                        self.field(key, names_buffer, child, at, out);
                        self.walk(child, at, out);
                    }
                    at.truncate(len);
                }
            }
            Value::Sequence(items) => {
                for (i, child) in items.iter().enumerate() {
                    let _ = write!(at, "[{i}]");
                    self.walk(child, at, out);
                    at.truncate(len);
                }
            }
            Value::Tagged(t) => {
                self.tagged(&t.tag.to_string(), &t.value, at, out);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The walk over the whole case document, as the reference for the parts it is given.
    fn flaws_of_whole_document(case: &Case) -> Vec<Flaw> {
        let doc = serde_yaml::to_value(case).expect("a case serialises");
        let groups = case
            .as_trace()
            .map(|t| t.world.pipeline.as_ref().map(|p| p.groups.len()));
        let names = |list: &str| -> BTreeSet<String> {
            doc.get("world")
                .and_then(|w| w.get(list))
                .and_then(Value::as_sequence)
                .map(|items| {
                    items
                        .iter()
                        .filter_map(|v| Some(v.get("name")?.as_str()?.to_string()))
                        .collect()
                })
                .unwrap_or_default()
        };
        let scope = Scope {
            buffers: names("buffers"),
            structures: names("structures"),
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
}
