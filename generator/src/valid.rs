//! Valid-by-construction plans: strategies draw small indices and selectors, and [`resolve`] turns
//! them into a plan whose every rule holds (no filtering): records each ray reaches hold a group of
//! the matching kind or zero, strides and offsets come from the profile's alignments and limits.

use crate::aim;
use crate::plan::{device_state, queue_families, round_up, IndirectPlan, Limits, Plan, TablePlan};
use crate::scenes::{self, SceneDraw};
use model::flags::{PipelineCreate, QueueFlags};
use model::scene::Ray;
use model::world::{
    CommandBufferState, GeneralStage, GeometryKind, HandleRef, Launch, ShaderGroup,
};
use model::CommandId;
use model::{DeviceProfile, Table};
use proptest::prelude::*;
use std::collections::BTreeMap;

/// How large launch dimensions are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum DimensionRange {
    /// 0 to 4 per dimension.
    #[default]
    Small,
    /// Up to the profile's limits (per dimension and, for KHR, the invocation count).
    Limits,
}

/// The drawn indices a plan is resolved from.
#[derive(Debug, Clone)]
pub struct Raw {
    pub miss_groups: usize,
    /// (procedural, closest-hit, any-hit) per hit group.
    pub hit_groups: Vec<(bool, bool, bool)>,
    pub callable_groups: usize,
    /// Geometries (true: AABBs) and the SBT record offset of each instance.
    pub instances: Vec<(Vec<bool>, u32)>,
    /// (target selector, miss index, sbt offset, sbt stride) per ray.
    pub rays: Vec<(u8, u32, u32, u32)>,
    pub callables: Vec<u32>,
    pub extra_recursion: u32,
    pub spare_depth: u32,
    pub record_sel: Vec<u8>,
    /// Unreached records appended to miss, hit, callable.
    pub extra_records: [u8; 3],
    /// Whether miss, hit, callable tables are set even when nothing reaches them.
    pub keep_idle: [bool; 3],
    pub stride_sel: [u8; 4],
    pub size_sel: [u8; 4],
    pub lead: [u8; 4],
    pub separate: [bool; 4],
    pub tail: u8,
    /// Per dimension: (selector, fraction).
    pub dims: [(u8, u32); 3],
    pub indirect_off: u8,
    pub indirect_slack: u8,
    pub no_null: [bool; 4],
    pub dynamic_stack: bool,
    pub queue_sel: u8,
}

/// The strategy for the drawn indices.
pub fn raw_strategy() -> impl Strategy<Value = Raw> {
    let groups = (
        0..=3usize,
        prop::collection::vec((any::<bool>(), any::<bool>(), any::<bool>()), 0..=3),
        0..=2usize,
    );
    let scene = (
        prop::collection::vec(
            (prop::collection::vec(any::<bool>(), 1..=2), 0..=2u32),
            0..=2,
        ),
        prop::collection::vec((any::<u8>(), 0..=2u32, 0..=1u32, 0..=1u32), 0..=3),
        prop::collection::vec(0..=1u32, 0..=2),
        0..=1u32,
        0..=1u32,
    );
    let layout = (
        prop::collection::vec(any::<u8>(), 12),
        prop::array::uniform3(0..=1u8),
        prop::array::uniform3(any::<bool>()),
        prop::array::uniform4(any::<u8>()),
        prop::array::uniform4(0..=2u8),
        prop::array::uniform4(0..=1u8),
        prop::array::uniform4(any::<bool>()),
        0..=2u8,
    );
    let misc = (
        prop::array::uniform3((0..=2u8, any::<u32>())),
        0..=3u8,
        0..=2u8,
        prop::array::uniform4(prop::bool::weighted(0.25)),
        any::<bool>(),
        any::<u8>(),
    );
    (groups, scene, layout, misc).prop_map(|(g, s, l, m)| Raw {
        miss_groups: g.0,
        hit_groups: g.1,
        callable_groups: g.2,
        instances: s.0,
        rays: s.1,
        callables: s.2,
        extra_recursion: s.3,
        spare_depth: s.4,
        record_sel: l.0,
        extra_records: l.1,
        keep_idle: l.2,
        stride_sel: l.3,
        size_sel: l.4,
        lead: l.5,
        separate: l.6,
        tail: l.7,
        dims: m.0,
        indirect_off: m.1,
        indirect_slack: m.2,
        no_null: m.3,
        dynamic_stack: m.4,
        queue_sel: m.5,
    })
}

/// Group indices of each kind in a plan's pipeline.
pub struct GroupIndex {
    pub miss: Vec<u32>,
    pub triangles: Vec<u32>,
    pub procedural: Vec<u32>,
    pub callable: Vec<u32>,
}

impl GroupIndex {
    pub fn of(groups: &[ShaderGroup]) -> GroupIndex {
        let mut g = GroupIndex {
            miss: vec![],
            triangles: vec![],
            procedural: vec![],
            callable: vec![],
        };
        for (i, sg) in groups.iter().enumerate() {
            let i = i as u32;
            match sg {
                ShaderGroup::General {
                    stage: GeneralStage::Miss,
                } => g.miss.push(i),
                ShaderGroup::General {
                    stage: GeneralStage::Callable,
                } => g.callable.push(i),
                ShaderGroup::General {
                    stage: GeneralStage::Raygen,
                } => {}
                ShaderGroup::TrianglesHit { .. } => g.triangles.push(i),
                ShaderGroup::ProceduralHit { .. } => g.procedural.push(i),
            }
        }
        g
    }
}

fn pick<T: Copy>(options: &[T], sel: u8) -> T {
    options[sel as usize % options.len()]
}

/// A dimension drawn up to `max`: the maximum, 1, or a fraction of the way.
fn pick_dim(max: u64, (sel, frac): (u8, u32)) -> u32 {
    let max = max.min(u32::MAX as u64);
    if max == 0 {
        return 0;
    }
    match sel {
        0 => max as u32,
        1 => 1,
        _ => (1 + (max - 1) * frac as u64 / u32::MAX as u64) as u32,
    }
}

/// Dimensions within the profile's limits, each and (KHR) their product.
pub fn limit_dims(lim: &Limits, raw: &[(u8, u32); 3]) -> [u32; 3] {
    within_limits(lim, |i, most| pick_dim(most, raw[i]))
}

/// `wanted` cut to the profile's limits: each dimension to its most, then (KHR) dimension by
/// dimension to what `maxRayDispatchInvocationCount` leaves. A profile reporting less than the
/// specification requires (a conformance finding) still gets only cases valid on it.
pub fn fit_dims(lim: &Limits, wanted: [u32; 3]) -> [u32; 3] {
    within_limits(lim, |i, most| u64::from(wanted[i]).min(most) as u32)
}

/// Each dimension `dim(i, most)` with `most` the largest it may be: its own limit, and (KHR) what
/// `maxRayDispatchInvocationCount` leaves after the dimensions before it.
fn within_limits(lim: &Limits, mut dim: impl FnMut(usize, u64) -> u32) -> [u32; 3] {
    let cap = lim.max_invocations.unwrap_or(u64::MAX);
    let mut out = [0u32; 3];
    let mut product = 1u64;
    for (i, d) in out.iter_mut().enumerate() {
        let room = cap / product.max(1);
        *d = dim(i, lim.max_dim[i].min(room));
        product = product.saturating_mul(u64::from((*d).max(1)));
    }
    out
}

/// The drawn indices a rendered case keeps: its pipeline is only what its scene needs — two miss
/// groups, and hit groups of the scene's kind beside the draw's own (two more like it: closest-hit,
/// and any-hit by the draw's rule), no callables, no extra recursion, no NO_NULL flags and no dynamic
/// stack. Those vary in the plain valid cases; here they would make nearly every rendered case a
/// pipeline of its own, and a driver compiles each (lavapipe lowers a whole ray tracing pipeline into
/// one compute shader). Rendered cases then share a handful of pipelines (one per kind and any-hit
/// rule) while their SBT records still point at distinct hit groups.
fn for_scene(raw: &Raw, d: &SceneDraw) -> Raw {
    let procedural = scenes::is_procedural(d);
    let any_hit = scenes::any_hit_rule(d).is_some();
    Raw {
        miss_groups: 2,
        hit_groups: vec![(procedural, true, any_hit); 2],
        callable_groups: 0,
        callables: vec![],
        extra_recursion: 0,
        spare_depth: 0,
        no_null: [false; 4],
        dynamic_stack: false,
        ..raw.clone()
    }
}

/// How many canonical pipelines the base worlds of invalid cases draw from ([`canonical_base`]).
pub const CANONICAL_PIPELINES: u32 = 6;

/// The canonical pipeline shapes: (miss groups, (procedural, closest-hit, any-hit) per hit group,
/// callable groups, maximum recursion depth, dynamic stack size). Between them every group kind and
/// shader (so a resource state's accesses can land in every stage a launch reaches), static and
/// dynamic stack; at most four stages each, since a driver's compile grows with them (lavapipe's
/// about doubles from one stage to three and again to seven); the depth at least what any drawn
/// launch needs (1 + the drawn extra recursion).
type Shape = (usize, &'static [(bool, bool, bool)], usize, u32, bool);
const SHAPES: [Shape; CANONICAL_PIPELINES as usize] = [
    (0, &[], 0, 2, false),
    (1, &[(false, true, false)], 0, 2, false),
    (1, &[(true, true, false)], 0, 2, true),
    (0, &[(false, true, false)], 1, 3, true),
    (1, &[(true, false, false)], 1, 2, false),
    (1, &[(false, false, true)], 0, 3, false),
];

/// The base plan of an invalid case: the drawn plan with its pipeline replaced by canonical shape
/// `shape` (of [`CANONICAL_PIPELINES`]). An invalid case is about the one rule its mutation breaks;
/// the pipeline it runs need not be new, and a pipeline that is not new is a compile the driver need
/// not do (lavapipe lowers every ray tracing pipeline into one compute shader, which is most of an
/// invalid case's time). The seed still picks among the shapes, and records, tables, scene, rays and
/// launch still vary. Valid cases keep their drawn pipelines: they are what a driver runs. A mutation
/// that edits the pipeline itself starts from the drawn one instead (see `mutation::edits_pipeline`).
pub fn canonical_base(
    raw: &Raw,
    shape: u32,
    profile: &DeviceProfile,
    lim: &Limits,
    command: CommandId,
    dims: DimensionRange,
) -> Plan {
    let (miss, hits, callables, depth, dynamic) = SHAPES[shape as usize % SHAPES.len()];
    let fixed = Raw {
        miss_groups: miss,
        hit_groups: hits.to_vec(),
        callable_groups: callables,
        // No NO_NULL flags: they are kept or dropped by what the records reach, so the flags (part
        // of the pipeline) would vary with every draw.
        no_null: [false; 4],
        dynamic_stack: dynamic,
        ..raw.clone()
    };
    let mut plan = resolve(&fixed, profile, lim, command, dims, None);
    // The depth is the shape's, not the launch's need plus a drawn spare: still at least what the
    // launch needs and within the device's maximum (which `resolve` keeps the launch within).
    let max_dev = lim.max_recursion.min(u32::MAX as u64) as u32;
    plan.max_recursion_depth = depth.min(max_dev).max(plan.launch.recursion_depth());
    plan
}

/// Resolves drawn indices into a valid plan.
pub fn resolve(
    raw: &Raw,
    profile: &DeviceProfile,
    lim: &Limits,
    command: CommandId,
    dims: DimensionRange,
    rendered: Option<&SceneDraw>,
) -> Plan {
    let scene_raw = rendered.map(|d| for_scene(raw, d));
    let raw = scene_raw.as_ref().unwrap_or(raw);
    // Pipeline: raygen, miss, hit, callable groups.
    let mut groups = vec![ShaderGroup::General {
        stage: GeneralStage::Raygen,
    }];
    groups.extend((0..raw.miss_groups).map(|_| ShaderGroup::General {
        stage: GeneralStage::Miss,
    }));
    // A rendered case's hit groups all follow its draw's any-hit rule.
    let any_hit_rule = rendered.and_then(scenes::any_hit_rule).unwrap_or_default();
    for &(procedural, closest_hit, any_hit) in &raw.hit_groups {
        groups.push(if procedural {
            ShaderGroup::ProceduralHit {
                closest_hit,
                any_hit,
                any_hit_rule,
                intersection: true,
            }
        } else {
            ShaderGroup::TrianglesHit {
                closest_hit,
                any_hit,
                any_hit_rule,
            }
        });
    }
    if let Some(d) = rendered {
        // A rendered scene is seen through hit groups with closest-hit shaders of its kind (and the
        // draw's any-hit rule), and a miss shader.
        if raw.miss_groups == 0 {
            groups.insert(
                1,
                ShaderGroup::General {
                    stage: GeneralStage::Miss,
                },
            );
        }
        let rule = scenes::any_hit_rule(d);
        groups.push(if scenes::is_procedural(d) {
            ShaderGroup::ProceduralHit {
                closest_hit: true,
                any_hit: rule.is_some(),
                any_hit_rule: rule.unwrap_or_default(),
                intersection: true,
            }
        } else {
            ShaderGroup::TrianglesHit {
                closest_hit: true,
                any_hit: rule.is_some(),
                any_hit_rule: rule.unwrap_or_default(),
            }
        });
    }
    groups.extend((0..raw.callable_groups).map(|_| ShaderGroup::General {
        stage: GeneralStage::Callable,
    }));
    let gi = GroupIndex::of(&groups);

    // Scene and rays: aimed instances (one bottom level of one geometry kind each: a bottom level
    // holds geometries of one type, so the first draw decides) and rays aimed at their geometries or
    // beside them.
    // A rendered case traces its scene instead.
    let mut launch = Launch::default();
    let mut rendered_dims = None;
    if let Some(d) = rendered {
        let (l, dims) = scenes::realise(d);
        launch = l;
        rendered_dims = Some(dims);
    }
    let mut targets: Vec<Option<(u32, u32)>> = vec![None];
    for (geoms, off) in raw.instances.iter().filter(|_| rendered.is_none()) {
        let kind = if geoms.first() == Some(&true) {
            GeometryKind::Aabbs
        } else {
            GeometryKind::Triangles
        };
        // SPV_NV_ray_tracing has no geometry index, so the intersection shader of an NV pipeline
        // finds its sphere only in a procedural bottom level of one geometry.
        let n = if command.is_nv() && kind == GeometryKind::Aabbs {
            1
        } else {
            geoms.len()
        };
        let i = aim::add_instance(&mut launch, &vec![kind; n], *off, aim::AIMED_MASK);
        targets.extend((0..n as u32).map(|g| Some((i, g))));
    }
    if rendered.is_none() {
        launch.rays = raw
            .rays
            .iter()
            .map(|&(t, miss_index, sbt_offset, sbt_stride)| {
                let ray = match pick(&targets, t) {
                    Some((i, g)) => aim::ray_at(i, g, aim::AIMED_MASK),
                    None => aim::ray_beside(aim::AIMED_MASK),
                };
                Ray {
                    miss_index,
                    sbt_offset,
                    sbt_stride,
                    ..ray
                }
            })
            .collect();
    }
    let callables: Vec<u32> = if gi.callable.is_empty() {
        vec![]
    } else {
        raw.callables.clone()
    };

    // Which records the rays may reach (the model's reach, over every ray), and from which geometry
    // kinds; every ray's miss record counts as reached (a superset of the misses the tracer allows).
    let mut hit_reach: BTreeMap<u64, (bool, bool)> = BTreeMap::new();
    for (idx, kind) in model::semantics::launch_hit_reach(&launch, None) {
        let e = hit_reach.entry(idx).or_default();
        match kind {
            GeometryKind::Triangles => e.0 = true,
            GeometryKind::Aabbs => e.1 = true,
        }
    }
    let mut miss_reach: Vec<u64> = launch
        .rays
        .iter()
        .map(|r| model::semantics::miss_record(r.miss_index))
        .collect();
    if let Some(c) = &launch.camera {
        miss_reach.push(model::semantics::miss_record(c.miss_index));
    }

    // NO_NULL_* flags are requested by the draw and kept only where the pipeline can be created with
    // them (the shaders they require exist) and where the records can avoid zero.
    let hit_groups_all: Vec<u32> = gi.triangles.iter().chain(&gi.procedural).copied().collect();
    let all_hit =
        |f: &dyn Fn(&ShaderGroup) -> bool| hit_groups_all.iter().all(|&g| f(&groups[g as usize]));
    let no_null_miss = raw.no_null[0] && !gi.miss.is_empty();
    let no_null_any = raw.no_null[1]
        && all_hit(&|g| {
            matches!(
                g,
                ShaderGroup::TrianglesHit { any_hit: true, .. }
                    | ShaderGroup::ProceduralHit { any_hit: true, .. }
            )
        });
    let no_null_closest = raw.no_null[2]
        && all_hit(&|g| {
            matches!(
                g,
                ShaderGroup::TrianglesHit {
                    closest_hit: true,
                    ..
                } | ShaderGroup::ProceduralHit {
                    closest_hit: true,
                    ..
                }
            )
        });
    let no_null_isect = raw.no_null[3];

    let mut sel = raw.record_sel.iter().copied().cycle();
    let mut next = || sel.next().unwrap_or(0);

    // Hit records: candidates by the kinds that reach each record.
    let mut no_null_any = no_null_any;
    let mut no_null_closest = no_null_closest;
    let mut no_null_isect = no_null_isect;
    let hit_reached_n = hit_reach.keys().next_back().map_or(0, |m| m + 1);
    let hit_n = if hit_reached_n > 0 || (raw.keep_idle[1] && !hit_groups_all.is_empty()) {
        hit_reached_n + raw.extra_records[1] as u64
    } else {
        0
    };
    let mut hit_records = Vec::new();
    for idx in 0..hit_n {
        let mut cands: Vec<HandleRef> = match hit_reach.get(&idx) {
            Some((true, true)) => vec![],
            Some((true, false)) => gi.triangles.iter().map(|&g| HandleRef::Group(g)).collect(),
            Some((false, true)) => gi.procedural.iter().map(|&g| HandleRef::Group(g)).collect(),
            _ => hit_groups_all
                .iter()
                .map(|&g| HandleRef::Group(g))
                .collect(),
        };
        let reached = hit_reach.get(&idx);
        let zero_forbidden = reached
            .is_some_and(|(_, aabb)| no_null_any || no_null_closest || (no_null_isect && *aabb));
        if !zero_forbidden || cands.is_empty() {
            cands.push(HandleRef::Zero);
        }
        let h = pick(&cands, next());
        if h == HandleRef::Zero {
            if let Some((_, aabb)) = reached {
                // A zero record is reached: the flags that forbid it are dropped.
                no_null_any = false;
                no_null_closest = false;
                if *aabb {
                    no_null_isect = false;
                }
            }
        }
        hit_records.push(h);
    }

    // Miss records.
    let miss_reached_n = miss_reach.iter().max().map_or(0, |m| m + 1);
    let miss_n = if miss_reached_n > 0 || (raw.keep_idle[0] && !gi.miss.is_empty()) {
        miss_reached_n + raw.extra_records[0] as u64
    } else {
        0
    };
    let mut miss_records = Vec::new();
    for idx in 0..miss_n {
        let mut cands: Vec<HandleRef> = gi.miss.iter().map(|&g| HandleRef::Group(g)).collect();
        if !(no_null_miss && miss_reach.contains(&idx)) || cands.is_empty() {
            cands.push(HandleRef::Zero);
        }
        miss_records.push(pick(&cands, next()));
    }

    // Callable records: reached ones hold a callable group.
    let call_reached_n = callables.iter().max().map_or(0, |m| *m as u64 + 1);
    let call_n = if call_reached_n > 0 || (raw.keep_idle[2] && !gi.callable.is_empty()) {
        call_reached_n + raw.extra_records[2] as u64
    } else {
        0
    };
    let mut callable_records = Vec::new();
    for idx in 0..call_n {
        let mut cands: Vec<HandleRef> = gi.callable.iter().map(|&g| HandleRef::Group(g)).collect();
        if idx >= call_reached_n {
            cands.push(HandleRef::Zero);
        }
        callable_records.push(pick(&cands, next()));
    }

    let mut flags = PipelineCreate::empty();
    // NO_NULL_MISS needs a non-zero handle at the miss region's address (03511: record 0, reached or
    // not) and, so that no valid launch executes a null miss shader under it, at every reached record.
    if no_null_miss
        && miss_records.first().is_some_and(|h| *h != HandleRef::Zero)
        && !miss_reach
            .iter()
            .any(|&i| miss_records.get(i as usize) == Some(&HandleRef::Zero))
    {
        flags.insert(PipelineCreate::RAY_TRACING_NO_NULL_MISS_SHADERS_BIT_KHR);
    }
    if no_null_any {
        flags.insert(PipelineCreate::RAY_TRACING_NO_NULL_ANY_HIT_SHADERS_BIT_KHR);
    }
    // With the hit table unused, NO_NULL_CLOSEST_HIT and NO_NULL_INTERSECTION are violations (03696, 03697).
    if hit_records.is_empty() {
        no_null_closest = false;
        no_null_isect = false;
    }
    if no_null_closest {
        flags.insert(PipelineCreate::RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR);
    }
    if no_null_isect {
        flags.insert(PipelineCreate::RAY_TRACING_NO_NULL_INTERSECTION_SHADERS_BIT_KHR);
    }
    if command.is_nv() {
        // The NO_NULL flags are KHR pipeline flags.
        flags = PipelineCreate::empty();
    }

    // Recursion: within the pipeline's maximum, which is within the device's.
    launch.callables = callables;
    launch.extra_recursion = raw.extra_recursion;
    let max_dev = lim.max_recursion.min(u32::MAX as u64) as u32;
    if launch.recursion_depth() > max_dev {
        launch.extra_recursion = 0;
    }
    if launch.recursion_depth() > max_dev {
        launch.rays.clear();
        launch.camera = None;
        launch.callables.clear();
    }
    let max_recursion_depth = (launch.recursion_depth() + raw.spare_depth).min(max_dev);

    // Tables: strides from the profile's choices, sizes exactly the records or larger.
    let strides = lim.stride_choices();
    let records = [
        vec![HandleRef::Group(0)],
        miss_records,
        hit_records,
        callable_records,
    ];
    let tables: [TablePlan; 4] = std::array::from_fn(|i| {
        let stride = pick(&strides, raw.stride_sel[i]);
        let size_extra = match raw.size_sel[i] {
            0 => 0,
            1 => lim.stride_align,
            _ => stride,
        };
        TablePlan {
            records: records[i].clone(),
            stride,
            size_extra,
            size_override: None,
            lead: raw.lead[i] as u64 * lim.base_align,
            misalign: 0,
            separate: raw.separate[i],
            buffer_size_override: None,
        }
    });

    let dims = match (rendered_dims, dims) {
        (Some(d), _) => d,
        (None, DimensionRange::Small) => fit_dims(
            lim,
            [raw.dims[0].1 % 5, raw.dims[1].1 % 5, raw.dims[2].1 % 5],
        ),
        (None, DimensionRange::Limits) => limit_dims(lim, &raw.dims),
    };

    let families: Vec<QueueFlags> = queue_families(profile)
        .into_iter()
        .filter(|q| q.contains(QueueFlags::COMPUTE_BIT))
        .collect();
    // An NV pipeline has no stack-size state (vkCreateRayTracingPipelinesNV takes no dynamic states).
    let dynamic_stack = raw.dynamic_stack && command != CommandId::TraceRaysNv;
    let command_buffer = CommandBufferState {
        pool_queue: if families.is_empty() {
            CommandBufferState::default().pool_queue
        } else {
            pick(&families, raw.queue_sel)
        },
        stack_size_set: dynamic_stack,
        ..Default::default()
    };

    Plan {
        command,
        device: device_state(profile, command),
        command_buffer,
        groups,
        flags,
        max_recursion_depth,
        dynamic_stack_size: dynamic_stack,
        launch,
        tables,
        sbt_tail: raw.tail as u64 * lim.stride_align,
        dims,
        indirect: IndirectPlan {
            offset: raw.indirect_off as u64 * 4,
            misalign: 0,
            slack: raw.indirect_slack as u64 * 4,
            buffer_size_override: None,
        },
    }
}

/// Used by mutations: whether a table index is one of the three launch-reached tables.
pub fn table_of(i: usize) -> Table {
    Table::ALL[i]
}

/// Rounds a buffer size up to a multiple of `align` (re-exported for mutations).
pub fn align_up(v: u64, align: u64) -> u64 {
    round_up(v, align)
}
