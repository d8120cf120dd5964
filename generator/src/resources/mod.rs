//! Resource worlds for the shared resource-access rules: a valid [`ResourceState`] built
//! from a device profile's formats (strategy [`state_strategy`]), and one mutation per executable
//! resource rule that makes exactly that rule fire, with the co-violations the captured devices make
//! unavoidable declared.
//!
//! Mutations are named by the VUID tag they break ([`ResourceMutation`]); [`mutate`] edits a world
//! in place and is what [`apply`] (called by `generator::mutation` for resource rules) and the tests call.

mod edit;
mod mutate;
mod valid;
mod wide;

pub use mutate::mutate;
pub use valid::{state_strategy, valid_state, LAYOUT, SET, SET_LAYOUT};

use crate::mutation_io::{Mutated, MutationInput};
use crate::plan::{realize, Plan};
use crate::GenError;
use model::resources::formats::{self, Usage};
use model::resources::*;
use model::world::{CommandBufferState, DeviceState};
use model::DeviceProfile;
use vk_registry::vuid::Condition;

/// The rule tags with a mutation, and whether the rule needs an extension no captured driver has.
pub const TAGS: &[(&str, Option<&str>)] = &[
    ("02697", None),
    ("08600", None),
    ("02698", None),
    ("06425", None),
    ("08602", None),
    ("08601", None),
    ("02699", None),
    ("08114", None),
    ("08116", None),
    ("08115", None),
    ("08117", None),
    ("08119", None),
    ("02702", None),
    ("08609", None),
    ("09636", None),
    ("02703", None),
    ("08610", None),
    ("02704", None),
    ("08611", None),
    ("09635", None),
    ("02705", None),
    ("02706", None),
    ("06935", None),
    ("06936", None),
    ("02691", None),
    ("07888", None),
    ("02692", Some("cubic")),
    ("02693", Some("cubic")),
    ("02694", Some("cubic")),
    ("02695", Some("cubic")),
    ("09212", Some("cubic")),
    ("09213", Some("cubic")),
    ("09214", Some("cubic")),
    ("02696", None),
    ("04115", None),
    ("08795", None),
    ("04469", None),
    ("08796", None),
    ("04470", None),
    ("04471", None),
    ("04472", None),
    ("04473", None),
    ("04474", None),
    ("04475", None),
    ("04553", None),
    ("04770", None),
    ("09598", None),
    ("09599", None),
    ("06478", None),
    ("06479", None),
    ("06550", None),
    ("06551", None),
    ("06971", Some("qcom")),
    ("06972", Some("qcom")),
    ("06973", Some("qcom")),
    ("06974", Some("qcom")),
    ("06975", Some("qcom")),
    ("09215", Some("qcom")),
    ("09216", Some("qcom")),
    ("06976", Some("qcom")),
    ("09217", Some("qcom")),
    ("06977", Some("qcom")),
    ("06978", Some("qcom")),
    ("07027", None),
    ("07028", None),
    ("07029", None),
    ("07030", None),
    ("07752", None),
    ("07753", None),
    ("09600", None),
    ("10068", None),
    ("09900", Some("tensor")),
    ("09905", Some("tensor")),
    ("09906", Some("tensor")),
    ("10678", Some("tile")),
    ("10679", Some("tile")),
    ("10746", Some("tile")),
];

/// A mutation that breaks the resource rule with this VUID tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResourceMutation {
    pub tag: &'static str,
}

/// The resource mutation for a trace command's VUID, if it is a resource rule.
pub fn mutation_for(vuid: &str) -> Option<ResourceMutation> {
    let rest = vuid.strip_prefix("VUID-")?;
    let (scope, rest) = rest.split_once('-')?;
    if !model::CommandId::from_vk_name(scope).is_some_and(model::CommandId::is_trace) {
        return None;
    }
    let tag = rest.rsplit('-').next()?;
    TAGS.iter()
        .find(|(t, _)| *t == tag)
        .map(|(t, _)| ResourceMutation { tag: t })
}

/// Vendor families: no captured driver has the extension, so cases are model-only.
pub fn vendor(m: ResourceMutation) -> Option<&'static str> {
    TAGS.iter().find(|(t, _)| *t == m.tag).and_then(|(_, v)| *v)
}

/// Refuses a mutation of a vendor family: no captured driver has its extension.
fn vendor_only(m: ResourceMutation, profile: &DeviceProfile) -> Result<(), GenError> {
    match vendor(m) {
        Some(family) => Err(GenError::Unsupported(format!(
            "resource rule {} ({family}) needs an extension `{}` lacks; the model judges such cases, no captured driver can run them",
            m.tag, profile.name
        ))),
        None => Ok(()),
    }
}

/// Whether the mutation can be generated for a profile: a dry run on a valid state of its own.
/// Asked once per spec (`crate::check_spec`); each case's own mutation reports what it cannot do.
pub fn supported(m: ResourceMutation, profile: &DeviceProfile) -> Result<(), GenError> {
    vendor_only(m, profile)?;
    let mut st = valid_state(profile, 0, u32::MAX);
    let mut dev = DeviceState::default();
    let mut cb = CommandBufferState::default();
    mutate(m, &mut st, &mut dev, &mut cb, profile, 0)
        .map(|_| ())
        .map_err(GenError::Unsupported)
}

// ---------------------------------------------------------------------------------------------
// Valid states

/// Makes a registry condition hold on the case's device by enabling extensions the profile has
/// (and leaving out the ones it negates). False when it cannot.
pub fn satisfy(
    c: &Condition,
    profile: &DeviceProfile,
    exts: &mut std::collections::BTreeSet<String>,
) -> bool {
    let (major, minor) = profile.api_major_minor();
    let version = |n: &str| {
        n.strip_prefix("VK_VERSION_").map(|v| {
            let mut it = v.split('_').map(|p| p.parse::<u32>().unwrap_or(0));
            (major, minor) >= (it.next().unwrap_or(1), it.next().unwrap_or(0))
        })
    };
    match c {
        Condition::Always => true,
        Condition::Ext(n) => match version(n) {
            Some(v) => v,
            None if exts.contains(n) => true,
            None if profile.has_extension(n) => {
                exts.insert(n.clone());
                true
            }
            None => false,
        },
        Condition::Not(inner) => {
            let names: Vec<String> = inner.names().into_iter().map(String::from).collect();
            for n in &names {
                if version(n).is_none() {
                    exts.remove(n);
                }
            }
            !inner.eval(&|n: &str| version(n).unwrap_or_else(|| exts.contains(n)))
        }
        Condition::All(v) => v.iter().all(|x| satisfy(x, profile, exts)),
        Condition::Any(v) => {
            if c.eval(&|n: &str| version(n).unwrap_or_else(|| exts.contains(n))) {
                return true;
            }
            v.iter().any(|x| satisfy(x, profile, exts))
        }
    }
}

/// The ray tracing stages a launch executes, by the model's semantics: the raygen, the miss, closest-hit
/// and intersection shaders of the records its rays reach ([`model::semantics::records_read`]) and the
/// callables it executes. Any-hit shaders are left out: whether one runs depends on opacity, which the
/// world does not describe. Sorted, without repeats.
pub fn launch_stages(world: &model::world::World, call: &model::call::Call) -> Vec<Stage> {
    use model::call::Table;
    use model::semantics::{record_handle, records_read};
    use model::world::{GeneralStage, HandleRef, ShaderGroup};
    let mut out = vec![];
    let records = records_read(world, call);
    if !records.is_empty() {
        out.push(Stage::Raygen);
    }
    for (table, index) in records {
        let group = match record_handle(world, call, table, index) {
            Some(HandleRef::Group(g)) => world
                .pipeline
                .as_ref()
                .and_then(|p| p.groups.get(g as usize)),
            _ => None,
        };
        match (table, group) {
            (
                Table::Miss,
                Some(ShaderGroup::General {
                    stage: GeneralStage::Miss,
                }),
            ) => out.push(Stage::Miss),
            (
                Table::Callable,
                Some(ShaderGroup::General {
                    stage: GeneralStage::Callable,
                }),
            ) => out.push(Stage::Callable),
            (
                Table::Hit,
                Some(ShaderGroup::TrianglesHit {
                    closest_hit: true, ..
                }),
            ) => out.push(Stage::ClosestHit),
            (
                Table::Hit,
                Some(ShaderGroup::ProceduralHit {
                    intersection: true,
                    closest_hit,
                    ..
                }),
            ) => {
                // An AABB ray reaches this record only when it targets an AABB geometry, which the
                // intersection shader reports (semantics.md §3).
                out.push(Stage::Intersection);
                if *closest_hit {
                    out.push(Stage::ClosestHit);
                }
            }
            _ => {}
        }
    }
    out.sort();
    out.dedup();
    out
}

/// Moves the state's declared accesses and push constant reads (all in the first stage, as
/// [`valid_state`] and [`mutate`] place them) into `stage`.
pub fn move_to_stage(st: &mut ResourceState, stage: Stage) {
    if st.stages.is_empty() || stage == Stage::Raygen {
        return;
    }
    st.stages[0].stage = stage;
}

/// What `generator::mutation` calls for a resource rule: a valid plan realised, a valid resource state added, the rule broken.
pub fn apply(
    m: ResourceMutation,
    mut plan: Plan,
    input: &MutationInput,
) -> Result<Mutated, GenError> {
    // The dry run of `supported` was made for the spec; only the cheap refusal is asked again.
    vendor_only(m, input.profile)?;
    // Accesses are judged only for launches that run: no dimension is zero.
    for d in plan.dims.iter_mut() {
        *d = (*d).max(1);
    }
    let (mut world, call) = realize(&plan, input.lim);
    let mut st = valid_state(
        input.profile,
        input.pick * 5 + input.knob,
        input.pick.wrapping_mul(97) ^ 0x1ff,
    );
    let tags = mutate(
        m,
        &mut st,
        &mut world.device,
        &mut world.command_buffer,
        input.profile,
        input.knob,
    )
    .map_err(GenError::Unsupported)?;
    // The accesses go into one of the stages the launch executes (the raygen always runs), so every
    // stage's shader is exercised across cases and a valid case's accesses really run.
    let stages = launch_stages(&world, &call);
    if !stages.is_empty() {
        move_to_stage(&mut st, stages[input.pick as usize % stages.len()]);
    }
    world.resources = st;
    let scope = input.command.vk_name();
    // The targeted row's registry condition (a resource rule's extension) holds on the case's device.
    if let Some(row) = input.rules.row(input.vuid) {
        let mut exts = world.device.extensions.clone();
        if !satisfy(&row.condition, input.profile, &mut exts) {
            return Err(GenError::Unsupported(format!(
                "{}: its condition cannot hold on `{}`",
                input.vuid, input.profile.name
            )));
        }
        world.device.extensions = exts;
    }
    let also = tags
        .into_iter()
        .filter_map(|t| {
            input
                .rules
                .rows
                .iter()
                .find(|r| r.scope == scope && r.vuid.rsplit('-').next() == Some(t))
                .map(|r| r.vuid.clone())
        })
        .filter(|v| v != input.vuid)
        .collect();
    Ok(Mutated { world, call, also })
}
