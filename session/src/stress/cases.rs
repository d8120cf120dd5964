//! A stress family's generated case as ordinary valid trace cases: its scene and its rays (split
//! into launches the profile's dispatch limits hold) in a `vkCmdTraceRaysKHR` world whose pipeline
//! has one miss group and one triangle hit group with a closest-hit shader and an accepting any-hit
//! shader, so every candidate a driver finds lands in the record's seen slots.

use generator::plan::{
    device_state, queue_families, realize, IndirectPlan, Limits, Plan, TablePlan,
};
use model::flags::{PipelineCreate, QueueFlags};
use model::stress::StressCase;
use model::tracer::AnyHitRule;
use model::world::{
    CommandBufferState, GeneralStage, GeometryKind, HandleRef, Launch, ShaderGroup,
};
use model::{Body, Case, CommandId, DeviceProfile, Intent, TraceBody};
use std::ops::Range;

/// The command every stress case traces with.
pub const STRESS_COMMAND: CommandId = CommandId::TraceRays;

/// The most rays one stress launch carries (a bound on one case's record buffer and on the time a
/// worker holds one case), below what the profile's limits allow.
pub const MAX_RAYS_PER_CASE: usize = 1 << 16;

/// The most hit or miss records a stress case's tables hold.
const MAX_RECORDS: u64 = 1024;

/// One trace case of a stress case: the launch of rays `rays` of it.
#[derive(Debug, Clone)]
pub struct StressLaunch {
    pub case: Case,
    pub rays: Range<usize>,
}

/// The pipeline's groups: raygen 0, miss 1, the triangle hit group 2.
fn groups() -> Vec<ShaderGroup> {
    vec![
        ShaderGroup::General {
            stage: GeneralStage::Raygen,
        },
        ShaderGroup::General {
            stage: GeneralStage::Miss,
        },
        ShaderGroup::TrianglesHit {
            closest_hit: true,
            any_hit: true,
            any_hit_rule: AnyHitRule::Accept,
        },
    ]
}

/// How many rays one launch may carry on `profile`: its dispatch limits, at most
/// [`MAX_RAYS_PER_CASE`].
pub fn rays_per_launch(lim: &Limits) -> usize {
    let cap = lim.max_dim[0].min(lim.max_invocations.unwrap_or(u64::MAX));
    (cap.min(MAX_RAYS_PER_CASE as u64) as usize).max(1)
}

/// The trace cases of `stress` on `profile`: its rays in launches of at most
/// [`rays_per_launch`], each launch ID tracing one ray. Err when the profile cannot lay out a
/// `vkCmdTraceRaysKHR` case (no ray tracing pipeline properties) or the scene holds a geometry
/// the stress pipeline has no hit group for.
pub fn trace_cases(
    stress: &StressCase,
    profile: &DeviceProfile,
    profile_name: &str,
    seed: u64,
) -> Result<Vec<StressLaunch>, String> {
    let lim = Limits::for_command(profile, STRESS_COMMAND).map_err(|e| e.to_string())?;
    let per = rays_per_launch(&lim);
    let count = stress.rays.len().div_ceil(per);
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let rays = k * per..((k + 1) * per).min(stress.rays.len());
        let name = if count == 1 {
            format!("stress/{}", stress.name)
        } else {
            format!("stress/{}/{k}", stress.name)
        };
        let launch = Launch {
            scene: stress.scene.clone(),
            rays: stress.rays[rays.clone()].to_vec(),
            ..Launch::default()
        };
        let case = launch_case(name, launch, profile, profile_name, seed, &lim)?;
        out.push(StressLaunch { case, rays });
    }
    Ok(out)
}

/// One valid case tracing `launch` (one launch ID per ray, x fastest).
fn launch_case(
    name: String,
    launch: Launch,
    profile: &DeviceProfile,
    profile_name: &str,
    seed: u64,
    lim: &Limits,
) -> Result<Case, String> {
    let hit_reach = model::semantics::launch_hit_reach(&launch, None);
    if let Some((i, _)) = hit_reach
        .iter()
        .find(|(_, k)| *k != GeometryKind::Triangles)
    {
        return Err(format!(
            "{name}: hit record {i} is reached from procedural geometry; the stress pipeline has triangle hit groups only"
        ));
    }
    let hit_n = hit_reach.iter().map(|(i, _)| i + 1).max().unwrap_or(0);
    let miss_n = launch
        .rays
        .iter()
        .map(|r| model::semantics::miss_record(r.miss_index) + 1)
        .max()
        .unwrap_or(0);
    if hit_n > MAX_RECORDS || miss_n > MAX_RECORDS {
        return Err(format!(
            "{name}: the rays reach {hit_n} hit and {miss_n} miss records; a stress case holds at most {MAX_RECORDS}"
        ));
    }
    let stride = lim.min_stride();
    let table = |records: Vec<HandleRef>| TablePlan {
        records,
        stride,
        ..TablePlan::unused()
    };
    let pool_queue = queue_families(profile)
        .into_iter()
        .find(|q| q.contains(QueueFlags::COMPUTE_BIT))
        .unwrap_or(CommandBufferState::default().pool_queue);
    let depth = launch.recursion_depth();
    if depth as u64 > lim.max_recursion {
        return Err(format!(
            "{name}: the launch needs recursion depth {depth}, the profile allows {}",
            lim.max_recursion
        ));
    }
    let rays = launch.rays.len() as u32;
    let plan = Plan {
        command: STRESS_COMMAND,
        device: device_state(profile, STRESS_COMMAND),
        command_buffer: CommandBufferState {
            pool_queue,
            ..CommandBufferState::default()
        },
        groups: groups(),
        flags: PipelineCreate::empty(),
        max_recursion_depth: depth,
        dynamic_stack_size: false,
        launch,
        tables: [
            table(vec![HandleRef::Group(0)]),
            table(vec![HandleRef::Group(1); miss_n as usize]),
            table(vec![HandleRef::Group(2); hit_n as usize]),
            TablePlan::unused(),
        ],
        sbt_tail: 0,
        dims: [rays, 1, 1],
        indirect: IndirectPlan {
            offset: 0,
            misalign: 0,
            slack: 0,
            buffer_size_override: None,
        },
    };
    let (world, call) = realize(&plan, lim);
    Ok(Case {
        name,
        profile: profile_name.to_string(),
        seed: Some(seed.to_string()),
        intent: Intent::Valid,
        body: Body::Trace(TraceBody { world, call }),
    })
}
