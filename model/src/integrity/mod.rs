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
//!
//! The references are found by a walk over the case's YAML form (`Scope::walk` over the
//! `serde_yaml::Value` of the parts that can hold one), which knows names by the keys and tags they
//! stand under, not by the Rust types that hold them. The run's gate asks this of every case, and
//! building and dropping that value tree is most of what the walk costs, so [`flaws`] makes the same
//! walk while the same parts serialise (`Stream`): a `serde::Serializer` that reads each value as
//! `serde_yaml::to_value` represents it and keeps only the path, the keys of the open mappings and
//! what their checks must know at their end. Where it meets what it does not represent with
//! certainty, it gives up and the value tree is built and walked.

use crate::case::{Body, Case};
use serde_yaml::Value;
use std::collections::BTreeSet;
use stream::{Stream, Unmirrored};

mod stream;

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
/// purpose), and its call. A rendered scene's thousands of coordinates are never serialised to be
/// walked.
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

/// The parts of a trace case that can hold references, borrowed from it.
fn trace_references(t: &crate::case::TraceBody) -> TraceReferences<'_> {
    use crate::call::Call;
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
    TraceReferences {
        world: WorldReferences {
            device,
            buffers,
            pipeline,
            command_buffer,
        },
        call,
    }
}

/// The case as a YAML value for the walk: every part that can hold a reference.
fn referencing_parts(case: &Case) -> Option<Value> {
    match case.as_trace() {
        Some(t) => serde_yaml::to_value(trace_references(t)).ok(),
        None => serde_yaml::to_value(case).ok(),
    }
}

/// Every error of the case, in the order of the file: found as the case's referencing parts
/// serialise, or, where that walk gives up, by walking their YAML value (the same errors either way).
pub fn flaws(case: &Case) -> Vec<Flaw> {
    streamed(case).unwrap_or_else(|_| flaws_of_value(case))
}

/// Every error of the case, found by building its referencing parts as a YAML value and walking it:
/// what [`flaws`] falls back to, and the reference the streamed walk is held to.
fn flaws_of_value(case: &Case) -> Vec<Flaw> {
    let Some(doc) = referencing_parts(case) else {
        return vec![];
    };
    let world = doc.get("world");
    let buffers = names(world, "buffers");
    let structures = names(world, "structures");
    let mut out = Vec::new();
    second_names("buffers", buffers.iter().copied(), &mut out);
    second_names("structures", structures.iter().copied(), &mut out);
    nv_dynamic_stack_size(case, &mut out);
    scopes_outside_recording(case, &mut out);
    let scope = Scope {
        buffers: buffers.into_iter().map(|(_, n)| n).collect(),
        structures: structures.into_iter().map(|(_, n)| n).collect(),
        groups: groups(case),
    };
    for key in ["world", "call"] {
        if let Some(v) = doc.get(key) {
            scope.walk(v, &mut key.to_string(), &mut out);
        }
    }
    out
}

/// Every error of the case, found by walking its referencing parts as they serialise ([`Stream`]);
/// an error where that walk meets what it does not represent as `serde_yaml::to_value` does.
fn streamed(case: &Case) -> Result<Vec<Flaw>, Unmirrored> {
    // The names are needed before the walk reaches them: read from the case, and checked by the walk
    // to be the names its YAML form holds where the value walk reads them.
    let (buffers, structures): (Vec<&str>, Vec<&str>) = match &case.body {
        Body::Trace(t) => (
            t.world.buffers.iter().map(|b| b.name.as_str()).collect(),
            Vec::new(),
        ),
        Body::Accel(a) => (
            a.world.buffers.iter().map(|b| b.name.as_str()).collect(),
            a.world.structures.iter().map(|s| s.name.as_str()).collect(),
        ),
    };
    let mut out = Vec::new();
    second_names("buffers", buffers.iter().copied().enumerate(), &mut out);
    second_names(
        "structures",
        structures.iter().copied().enumerate(),
        &mut out,
    );
    nv_dynamic_stack_size(case, &mut out);
    scopes_outside_recording(case, &mut out);
    let scope = Scope {
        buffers: buffers.iter().copied().collect(),
        structures: structures.iter().copied().collect(),
        groups: groups(case),
    };
    let named = [buffers.as_slice(), structures.as_slice()];
    match case.as_trace() {
        Some(t) => Stream::walk(&trace_references(t), &scope, named, out),
        None => Stream::walk(case, &scope, named, out),
    }
}

/// The names of the items of `world.<list>` that have one, with their indices.
fn names<'v>(world: Option<&'v Value>, list: &str) -> Vec<(usize, &'v str)> {
    world
        .and_then(|w| w.get(list))
        .and_then(Value::as_sequence)
        .map(|items| {
            items
                .iter()
                .enumerate()
                .filter_map(|(i, v)| Some((i, v.get("name")?.as_str()?)))
                .collect()
        })
        .unwrap_or_default()
}

/// A flaw for each item of `world.<list>` named as an earlier one is.
fn second_names<'n>(
    list: &str,
    named: impl IntoIterator<Item = (usize, &'n str)>,
    out: &mut Vec<Flaw>,
) {
    let mut seen = BTreeSet::new();
    for (i, n) in named {
        if !seen.insert(n) {
            out.push(Flaw {
                at: format!("world.{list}[{i}].name"),
                problem: format!("a second {} named `{n}`", &list[..list.len() - 1]),
            });
        }
    }
}

/// vkCreateRayTracingPipelinesNV takes no dynamic states: such a pipeline cannot exist.
fn nv_dynamic_stack_size(case: &Case, out: &mut Vec<Flaw>) {
    if let Some(p) = case.as_trace().and_then(|t| t.world.pipeline.as_ref()) {
        if p.api == crate::world::PipelineApi::Nv && p.dynamic_stack_size {
            out.push(Flaw {
                at: "world.pipeline.dynamic_stack_size".into(),
                problem: "an NV pipeline (vkCreateRayTracingPipelinesNV) has no dynamic states, so no dynamic stack size".into(),
            });
        }
    }
}

/// Scopes a command buffer in its state cannot be inside. One never begun (initial) has recorded
/// nothing and inherited nothing: no render pass instance, video coding scope or suspended render
/// pass instance. A primary one that was ended (executable) ended outside any render pass instance and
/// with no video session bound (VUID-vkEndCommandBuffer-commandBuffer-00060, -None-06991). A world
/// stating one of these describes nothing a driver can be given. A secondary command buffer begun with
/// RENDER_PASS_CONTINUE_BIT stays inside its render pass whatever its state, and an invalid one may
/// have been made invalid inside a scope: neither is a flaw.
fn scopes_outside_recording(case: &Case, out: &mut Vec<Flaw>) {
    use crate::world::{CommandBufferLevel, CommandBufferLifecycle as L};
    let cb = match &case.body {
        Body::Trace(t) => &t.world.command_buffer,
        Body::Accel(a) => &a.world.command_buffer,
    };
    // The scopes, the first `count` of which the state rules out.
    let scopes = [
        ("in_render_pass", cb.in_render_pass),
        ("in_video_coding", cb.in_video_coding),
        (
            "between_suspended_render_passes",
            cb.between_suspended_render_passes,
        ),
    ];
    let (state, count) = match (cb.lifecycle, cb.level) {
        (L::Initial, _) => (
            "initial: never begun, it has recorded and inherited nothing",
            3,
        ),
        (L::Executable, CommandBufferLevel::Primary) => (
            "executable: a primary command buffer ends outside any render pass instance and video coding scope (VUID-vkEndCommandBuffer-commandBuffer-00060, -None-06991)",
            2,
        ),
        _ => return,
    };
    for &(field, inside) in &scopes[..count] {
        if inside {
            out.push(Flaw {
                at: format!("world.command_buffer.{field}"),
                problem: format!("`{field}` cannot hold for a command buffer that is {state}"),
            });
        }
    }
}

/// For a trace case: the bound pipeline's group count (None: the world has no pipeline).
fn groups(case: &Case) -> Option<Option<usize>> {
    case.as_trace()
        .map(|t| t.world.pipeline.as_ref().map(|p| p.groups.len()))
}

/// The names a case's references must resolve to.
struct Scope<'n> {
    buffers: BTreeSet<&'n str>,
    structures: BTreeSet<&'n str>,
    /// For a trace case: the bound pipeline's group count (None: the world has no pipeline).
    groups: Option<Option<usize>>,
}

impl Scope<'_> {
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
                        out.extend(self.field(key, names_buffer, child.as_str(), at));
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
                let tag = t.tag.to_string();
                out.extend(self.tagged(&tag, t.value.as_u64(), t.value.as_str(), at));
                self.walk(&t.value, at, out);
            }
            _ => {}
        }
    }

    /// A named reference held in a field: the `buffer` of an address or of a build's structure, the
    /// `src`/`dst` of a build info. `name` is the field's value when it reads as a string.
    fn field(&self, key: &str, names_buffer: bool, name: Option<&str>, at: &str) -> Option<Flaw> {
        let name = name?;
        match key {
            "buffer" if names_buffer && !self.buffers.contains(name) => Some(Flaw {
                at: at.to_string(),
                problem: format!("names buffer `{name}`, which the world lacks"),
            }),
            "src" | "dst" if at.starts_with("call.infos[") && !self.structures.contains(name) => {
                Some(Flaw {
                    at: at.to_string(),
                    problem: format!(
                        "names acceleration structure `{name}`, which the world lacks"
                    ),
                })
            }
            _ => None,
        }
    }

    /// A tagged reference: `!group N` of a shader record, `!structure NAME` of an instance record.
    /// `number` and `name` are the tagged value when it reads as a non-negative integer or a string.
    fn tagged(&self, tag: &str, number: Option<u64>, name: Option<&str>, at: &str) -> Option<Flaw> {
        match tag.trim_start_matches('!') {
            "group" => {
                let (Some(groups), Some(n)) = (self.groups, number) else {
                    return None;
                };
                match groups {
                    None => Some(Flaw {
                        at: at.to_string(),
                        problem: format!("the handle of group {n}, but the world has no pipeline"),
                    }),
                    Some(len) if n >= len as u64 => Some(Flaw {
                        at: at.to_string(),
                        problem: format!(
                            "the handle of group {n}, but the pipeline has {len} group(s) (0 to {})",
                            len.saturating_sub(1)
                        ),
                    }),
                    Some(_) => None,
                }
            }
            "structure" => {
                let name = name?;
                (!self.structures.contains(name)).then(|| Flaw {
                    at: at.to_string(),
                    problem: format!(
                        "references acceleration structure `{name}`, which the world lacks"
                    ),
                })
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests;
