//! Executable predicates: the closed set of checks a rule row can run, each evaluated against a
//! prepared [`Context`] with no string work.

use super::Context;
use crate::call::{Call, Param, Table};
use crate::flags::{BufferUsage, PipelineCreate, QueueFlags};
use crate::semantics::record_handle;
use crate::world::{
    CommandBufferLifecycle, CommandBufferState, DeviceState, GeometryKind, HandleRef,
    MemoryBinding, ShaderGroup,
};

/// A number a rule compares against.
#[derive(Debug, Clone, PartialEq)]
pub enum Operand {
    Const(u64),
    /// A device limit, looked up in the profile (`Struct::member` or `Struct::member[i]`).
    Limit(String),
    /// The product of several operands (`maxComputeWorkGroupCount[0] × maxComputeWorkGroupSize[0]`).
    Product(Vec<Operand>),
    /// The size of the buffer the parameter's address or table lies in.
    SizeOfBufferOf(Param),
    /// Another parameter of the call.
    Param(Param),
}

/// What a compiled or hand-written rule checks.
#[derive(Debug, Clone, PartialEq)]
pub enum Predicate {
    /// `param % operand == 0`.
    MultipleOf(Param, Operand),
    /// `param <= operand`.
    AtMost(Param, Operand),
    /// `param < operand`.
    LessThan(Param, Operand),
    /// `param == operand`.
    Equal(Param, Operand),
    /// If the bound pipeline has the flag, the parameter must not be zero.
    NonZeroIfPipelineFlag(Param, PipelineCreate),
    /// If the bound pipeline has the flag, the named feature must be enabled.
    FeatureEnabledIfPipelineFlag(PipelineCreate, String),
    /// The buffer the parameter's address was queried from has the usage bit.
    BufferUsage(Param, BufferUsage),
    /// The buffer of the parameter, if not sparse, is bound completely and contiguously to one memory.
    BoundContiguously(Param),
    /// Every address of `[param, param + len)` lies in the same buffer; `len` from an operand.
    RangeInOneBuffer(Param, Operand),
    /// A region whose size is not zero lies inside one buffer (`VkStridedDeviceAddressRegionKHR-size-04631`).
    RegionInOneBuffer,
    /// A region whose size is not zero has a stride at most its buffer's size (`-size-04632`).
    RegionStrideWithinBuffer,
    /// The NV table's buffer, when given, is a buffer of the world.
    ValidBufferHandle(Table),
    /// The launch dimension `i` (for the indirect call: read from memory) is at most the operand.
    LaunchDimensionAtMost(u8, Operand),
    /// The product of the launch dimensions is at most the operand.
    LaunchInvocationsAtMost(Operand),
    /// A feature or command-buffer state rule, the same for every command.
    State(StatePredicate),
    PipelineBound,
    /// A pipeline is bound, judged only where the `shaderObject` feature is enabled (`true`, 08607) or
    /// not enabled (`false`, 08606): each VUID's text opens with that condition.
    PipelineBoundWhenShaderObject(bool),
    /// Hand rules that read the launch: see each variant's VUID in `hand.rs`.
    HandlesFromBoundPipeline,
    RecursionWithinPipelineLimit,
    NoNullMissAtRegionAddress,
    NoNullHitReached(NullHitKind),
    HitGroupTypeMatchesGeometry(GeometryKind),
    DynamicStackSizeSet,
    ClusterStructuresAllowed,
    NoStaticStateSet,
    NoProtectedResourceFromUnprotected,
    /// A resource-access rule shared with draw/dispatch, judged by `crate::resources`.
    Resource(crate::resources::ResourceRule),
    /// A rule of the build command's own, judged on the build world by `crate::accel::rules`.
    Accel(crate::accel::rules::AccelPredicate),
}

/// The rules every command shares: the enabled features and the command buffer's state.
#[derive(Debug, Clone, PartialEq)]
pub enum StatePredicate {
    /// The named feature must be enabled.
    FeatureEnabled(String),
    NotProtectedCommandBuffer,
    Recording,
    PoolSupports(QueueFlags),
    OutsideRenderPass,
    OutsideVideoCoding,
    NotBetweenSuspendedRenderPasses,
}

impl StatePredicate {
    /// The failure of the rule for a device state and a command buffer, if it fails.
    pub fn check(&self, device: &DeviceState, cb: &CommandBufferState) -> Option<Failure> {
        use StatePredicate as S;
        match self {
            S::FeatureEnabled(f) if !device.feature(f) => {
                fail("world.device.features", format!("`{f}` is not enabled"))
            }
            S::NotProtectedCommandBuffer if cb.protected => {
                fail("commandBuffer", "is a protected command buffer")
            }
            S::Recording if cb.lifecycle != CommandBufferLifecycle::Recording => fail(
                "commandBuffer",
                format!("is in the {:?} state", cb.lifecycle),
            ),
            S::PoolSupports(q) if !cb.pool_queue.intersects(*q) => fail(
                "commandBuffer",
                format!("its pool's queue family lacks {}", q.names().join(" or ")),
            ),
            S::OutsideRenderPass if cb.in_render_pass => {
                fail("commandBuffer", "is inside a render pass instance")
            }
            S::OutsideVideoCoding if cb.in_video_coding => {
                fail("commandBuffer", "is inside a video coding scope")
            }
            S::NotBetweenSuspendedRenderPasses if cb.between_suspended_render_passes => fail(
                "commandBuffer",
                "is between suspended render pass instances",
            ),
            _ => None,
        }
    }
}

/// Which NO_NULL_* hit flag a rule speaks of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NullHitKind {
    AnyHit,
    ClosestHit,
    Intersection,
}

/// One failed check: the parameter path and the problem.
pub struct Failure {
    pub context: String,
    pub problem: String,
}

impl Operand {
    /// The operand's value; None when a limit is missing from the profile (the rule is then not judged).
    fn value(&self, cx: &Context) -> Option<u64> {
        match self {
            Operand::Const(v) => Some(*v),
            Operand::Limit(name) => cx.profile.limit(name),
            Operand::Product(ops) => ops
                .iter()
                .try_fold(1u64, |a, o| Some(a.saturating_mul(o.value(cx)?))),
            Operand::SizeOfBufferOf(p) => cx.call.buffer_of(cx.world, *p).map(|b| b.size),
            Operand::Param(p) => Some(cx.call.value(*p)),
        }
    }

    fn describe(&self, cx: &Context) -> String {
        match self {
            Operand::Const(v) => v.to_string(),
            Operand::Limit(name) => format!(
                "{name} ({})",
                cx.profile.limit(name).map_or("?".into(), |v| v.to_string())
            ),
            Operand::Product(ops) => ops
                .iter()
                .map(|o| o.describe(cx))
                .collect::<Vec<_>>()
                .join(" × "),
            Operand::SizeOfBufferOf(p) => {
                format!("the size of the buffer of {}", cx.call.param_path(*p))
            }
            Operand::Param(p) => cx.call.param_path(*p),
        }
    }
}

fn fail(context: impl Into<String>, problem: impl Into<String>) -> Option<Failure> {
    Some(Failure {
        context: context.into(),
        problem: problem.into(),
    })
}

impl Operand {
    /// The operand with every device limit replaced by its value; None when the profile lacks one.
    fn resolved(&self, profile: &crate::profile::DeviceProfile) -> Option<Operand> {
        Some(match self {
            Operand::Limit(name) => Operand::Const(profile.limit(name)?),
            Operand::Product(ops) => Operand::Product(
                ops.iter()
                    .map(|o| o.resolved(profile))
                    .collect::<Option<Vec<_>>>()?,
            ),
            other => other.clone(),
        })
    }
}

impl Operand {
    /// The device limits the operand names that `profile` lacks.
    fn missing_limits(&self, profile: &crate::profile::DeviceProfile, out: &mut Vec<String>) {
        match self {
            Operand::Limit(name) if profile.limit(name).is_none() => out.push(name.clone()),
            Operand::Product(ops) => ops.iter().for_each(|o| o.missing_limits(profile, out)),
            _ => {}
        }
    }
}

impl Predicate {
    /// The device limits the predicate compares against that `profile` does not record: on that
    /// device the row is not judged ([`Predicate::for_device`] drops it), which a coverage report says.
    pub fn missing_limits(&self, profile: &crate::profile::DeviceProfile) -> Vec<String> {
        let mut out = Vec::new();
        match self {
            Predicate::MultipleOf(_, o)
            | Predicate::AtMost(_, o)
            | Predicate::LessThan(_, o)
            | Predicate::Equal(_, o)
            | Predicate::RangeInOneBuffer(_, o)
            | Predicate::LaunchDimensionAtMost(_, o)
            | Predicate::LaunchInvocationsAtMost(o) => o.missing_limits(profile, &mut out),
            _ => {}
        }
        out
    }

    /// The predicate for one device: limits looked up once (so judging a call does no string work), or
    /// None when the rule cannot apply there (a limit the profile lacks, `protectedNoFault` supported).
    pub fn for_device(&self, profile: &crate::profile::DeviceProfile) -> Option<Predicate> {
        Some(match self {
            Predicate::MultipleOf(p, o) => Predicate::MultipleOf(*p, o.resolved(profile)?),
            Predicate::AtMost(p, o) => Predicate::AtMost(*p, o.resolved(profile)?),
            Predicate::LessThan(p, o) => Predicate::LessThan(*p, o.resolved(profile)?),
            Predicate::Equal(p, o) => Predicate::Equal(*p, o.resolved(profile)?),
            Predicate::RangeInOneBuffer(p, o) => {
                Predicate::RangeInOneBuffer(*p, o.resolved(profile)?)
            }
            Predicate::LaunchDimensionAtMost(i, o) => {
                Predicate::LaunchDimensionAtMost(*i, o.resolved(profile)?)
            }
            Predicate::LaunchInvocationsAtMost(o) => {
                Predicate::LaunchInvocationsAtMost(o.resolved(profile)?)
            }
            Predicate::NoProtectedResourceFromUnprotected
                if profile.has_feature("protectedNoFault")
                    || profile.limit("protectedNoFault") == Some(1) =>
            {
                return None
            }
            other => other.clone(),
        })
    }

    /// Whether the parameter is part of the call at all (the raygen table has no stride for NV).
    fn applies(p: Param, call: &Call) -> bool {
        !matches!(
            (call, p),
            (Call::TraceRaysNv(_), Param::TableStride(Table::Raygen))
                | (Call::TraceRaysNv(_), Param::TableSize(_))
        )
    }

    /// Checks the predicate on a trace call; every failure found is pushed (a region rule may fail for
    /// several regions).
    pub fn check(&self, cx: &Context, out: &mut Vec<Failure>) {
        let call = cx.call;
        let world = cx.world;
        let mut push = |f: Option<Failure>| {
            if let Some(f) = f {
                out.push(f)
            }
        };
        match self {
            Predicate::State(p) => push(p.check(&world.device, &world.command_buffer)),
            // Judged on the build world (never active for a trace call).
            Predicate::Accel(_) => {}
            Predicate::Resource(r) => r.check(cx, out),
            Predicate::MultipleOf(p, op) => {
                if !Self::applies(*p, call) {
                    return;
                }
                let v = call.value(*p);
                if let Some(m) = op.value(cx) {
                    if m != 0 && v % m != 0 {
                        push(fail(
                            call.param_path(*p),
                            format!("{v} is not a multiple of {}", op.describe(cx)),
                        ));
                    }
                }
            }
            Predicate::AtMost(p, op) | Predicate::LessThan(p, op) | Predicate::Equal(p, op) => {
                if !Self::applies(*p, call) {
                    return;
                }
                // An NV table given no buffer is unused: offset rules about its buffer do not apply.
                if matches!(op, Operand::SizeOfBufferOf(_)) && call.buffer_of(world, *p).is_none() {
                    return;
                }
                let v = call.value(*p);
                let Some(m) = op.value(cx) else { return };
                let (ok, rel) = match self {
                    Predicate::AtMost(..) => (v <= m, "greater than"),
                    Predicate::LessThan(..) => (v < m, "not less than"),
                    _ => (v == m, "not equal to"),
                };
                if !ok {
                    push(fail(
                        call.param_path(*p),
                        format!("{v} is {rel} {}", op.describe(cx)),
                    ));
                }
            }
            Predicate::NonZeroIfPipelineFlag(p, flag) => {
                if let Some(pl) = world.bound_pipeline() {
                    let zero = call
                        .address(*p)
                        .map_or(call.value(*p) == 0, |a| a.is_null());
                    if pl.flags.contains(*flag) && zero {
                        push(fail(
                            call.param_path(*p),
                            format!("is zero but the pipeline has {}", flag.names().join("|")),
                        ));
                    }
                }
            }
            Predicate::FeatureEnabledIfPipelineFlag(flag, f) => {
                if world
                    .bound_pipeline()
                    .is_some_and(|pl| pl.flags.contains(*flag))
                    && !world.device.feature(f)
                {
                    push(fail(
                        "world.device.features",
                        format!(
                            "`{f}` is not enabled but the pipeline has {}",
                            flag.names().join("|")
                        ),
                    ));
                }
            }
            Predicate::BufferUsage(p, usage) => {
                if let Some(addr) = call.address(*p) {
                    if addr.is_null() {
                        return;
                    }
                }
                match call.buffer_of(world, *p) {
                    Some(b) if !b.usage.contains(*usage) => push(fail(
                        call.param_path(*p),
                        format!("buffer `{}` lacks {}", b.name, usage.names().join("|")),
                    )),
                    None if call.address(*p).is_some_and(|a| !a.is_null()) => push(fail(
                        call.param_path(*p),
                        "the address lies in no buffer of the world",
                    )),
                    _ => {}
                }
            }
            Predicate::BoundContiguously(p) => {
                if let Some(b) = call.buffer_of(world, *p) {
                    if !b.is_sparse() && b.memory != MemoryBinding::Whole {
                        push(fail(
                            call.param_path(*p),
                            format!("buffer `{}` is not bound to one memory object", b.name),
                        ));
                    }
                }
            }
            Predicate::RangeInOneBuffer(p, len) => {
                let Some(addr) = call.address(*p) else { return };
                let Some(len) = len.value(cx) else { return };
                match addr.buffer() {
                    Some((name, off)) => match world.buffer(name) {
                        Some(b) if off.saturating_add(len) <= b.size => {}
                        Some(b) => push(fail(
                            call.param_path(*p),
                            format!(
                                "[{off}, {off}+{len}) passes the end of `{}` ({} bytes)",
                                b.name, b.size
                            ),
                        )),
                        None => push(fail(
                            call.param_path(*p),
                            format!("no buffer `{name}` in the world"),
                        )),
                    },
                    None => push(fail(
                        call.param_path(*p),
                        "the address lies in no buffer of the world",
                    )),
                }
            }
            Predicate::RegionInOneBuffer | Predicate::RegionStrideWithinBuffer => {
                let Some(regions) = call.regions() else {
                    return;
                };
                for (t, r) in Table::ALL.iter().zip(regions) {
                    if r.size == 0 {
                        continue;
                    }
                    let ctx = t.khr_param();
                    let Some((name, off)) = r.address.buffer() else {
                        push(fail(
                            format!("{ctx}->deviceAddress"),
                            "a region of non-zero size lies in no buffer of the world",
                        ));
                        continue;
                    };
                    let Some(b) = world.buffer(name) else {
                        push(fail(
                            format!("{ctx}->deviceAddress"),
                            format!("no buffer `{name}` in the world"),
                        ));
                        continue;
                    };
                    if matches!(self, Predicate::RegionInOneBuffer) {
                        let end = off.saturating_add(r.size);
                        if end > b.size {
                            let over = end - b.size;
                            push(fail(
                                format!("{ctx}->size"),
                                format!(
                                    "[{off}, {off}+{}) passes the end of `{}` ({} bytes) by {over} byte{}",
                                    r.size,
                                    b.name,
                                    b.size,
                                    if over == 1 { "" } else { "s" }
                                ),
                            ));
                        }
                    } else if r.stride > b.size {
                        push(fail(
                            format!("{ctx}->stride"),
                            format!(
                                "{} is greater than the size of `{}` ({})",
                                r.stride, b.name, b.size
                            ),
                        ));
                    }
                }
            }
            Predicate::ValidBufferHandle(t) => {
                if let Some(Some(name)) = call.nv_table(*t).map(|n| n.buffer.as_ref()) {
                    if world.buffer(name).is_none() {
                        push(fail(
                            format!("{}TableBuffer", t.nv_stem()),
                            format!("`{name}` is not a buffer of the world"),
                        ));
                    }
                } else if *t == Table::Raygen && call.nv_table(*t).is_some() {
                    push(fail(
                        "raygenShaderBindingTableBuffer",
                        "VK_NULL_HANDLE is not a valid buffer",
                    ));
                }
            }
            Predicate::LaunchDimensionAtMost(i, op) => {
                if let (Some(d), Some(m)) = (call.dimensions(world), op.value(cx)) {
                    let v = d[*i as usize] as u64;
                    if v > m {
                        let field = ["width", "height", "depth"][*i as usize];
                        push(fail(
                            format!("indirect command.{field}"),
                            format!("{v} is greater than {}", op.describe(cx)),
                        ));
                    }
                }
            }
            Predicate::LaunchInvocationsAtMost(op) => {
                if let (Some(d), Some(m)) = (call.dimensions(world), op.value(cx)) {
                    // Three u32 dimensions may pass u64::MAX together; past it, the count is past any limit.
                    let v = d.iter().map(|&x| x as u64).fold(1u64, u64::saturating_mul);
                    if v > m {
                        push(fail(
                            "indirect command",
                            format!(
                                "width × height × depth = {v} is greater than {}",
                                op.describe(cx)
                            ),
                        ));
                    }
                }
            }
            Predicate::PipelineBound => {
                if world.bound_pipeline().is_none() {
                    push(fail("commandBuffer", "no ray tracing pipeline is bound"));
                }
            }
            Predicate::PipelineBoundWhenShaderObject(enabled) => {
                if world.device.feature("shaderObject") == *enabled
                    && world.bound_pipeline().is_none()
                {
                    push(fail("commandBuffer", "no ray tracing pipeline is bound"));
                }
            }
            Predicate::HandlesFromBoundPipeline => {
                for (table, index) in reached_records(cx) {
                    if let Some(HandleRef::Foreign(g)) = record_handle(world, call, table, index) {
                        push(fail(
                            format!("{table:?} record {index}"),
                            format!("holds group {g} of another pipeline"),
                        ));
                    }
                }
            }
            Predicate::RecursionWithinPipelineLimit => {
                if let Some(pl) = world.bound_pipeline() {
                    let depth = crate::semantics::recursion_depth(world, call);
                    if depth > pl.max_recursion_depth {
                        push(fail(
                            "world.launch",
                            format!(
                                "shader calls reach depth {depth}, the pipeline allows {}",
                                pl.max_recursion_depth
                            ),
                        ));
                    }
                }
            }
            Predicate::NoNullMissAtRegionAddress => {
                // 03511: "the shader group handle identified by pMissShaderBindingTable->deviceAddress
                // must not be zero" — the handle at the region's address (record 0), whether a ray
                // misses or not (unlike 03512-03514, which speak of entries accessed). A region whose
                // address is zero identifies no handle a miss could run, which the flag rules out too.
                let Some(pl) = world.bound_pipeline() else {
                    return;
                };
                if !pl
                    .flags
                    .contains(PipelineCreate::RAY_TRACING_NO_NULL_MISS_SHADERS_BIT_KHR)
                {
                    return;
                }
                let Some(region) = call.region(Table::Miss) else {
                    return;
                };
                if region.address.is_null() {
                    push(fail(
                        "pMissShaderBindingTable->deviceAddress",
                        "is zero but the pipeline has NO_NULL_MISS_SHADERS",
                    ));
                } else if record_handle(world, call, Table::Miss, 0) == Some(HandleRef::Zero) {
                    push(fail(
                        "pMissShaderBindingTable->deviceAddress",
                        "holds a zero group but the pipeline has NO_NULL_MISS_SHADERS",
                    ));
                }
            }
            Predicate::NoNullHitReached(kind) => {
                let Some(pl) = world.bound_pipeline() else {
                    return;
                };
                let flag = match kind {
                    NullHitKind::AnyHit => {
                        PipelineCreate::RAY_TRACING_NO_NULL_ANY_HIT_SHADERS_BIT_KHR
                    }
                    NullHitKind::ClosestHit => {
                        PipelineCreate::RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR
                    }
                    NullHitKind::Intersection => {
                        PipelineCreate::RAY_TRACING_NO_NULL_INTERSECTION_SHADERS_BIT_KHR
                    }
                };
                if !pl.flags.contains(flag) {
                    return;
                }
                for (index, geometry) in reached_hit_records(cx) {
                    let relevant =
                        *kind != NullHitKind::Intersection || geometry == GeometryKind::Aabbs;
                    if relevant
                        && record_handle(world, call, Table::Hit, index) == Some(HandleRef::Zero)
                    {
                        push(fail(
                            format!("hit record {index}"),
                            format!(
                                "is a zero group but the pipeline has {}",
                                flag.names().join("")
                            ),
                        ));
                    }
                }
            }
            Predicate::HitGroupTypeMatchesGeometry(kind) => {
                let Some(pl) = world.bound_pipeline() else {
                    return;
                };
                for (index, geometry) in reached_hit_records(cx) {
                    if geometry != *kind {
                        continue;
                    }
                    if let Some(HandleRef::Group(g)) = record_handle(world, call, Table::Hit, index)
                    {
                        let ok = matches!(
                            (pl.groups.get(g as usize), kind),
                            (
                                Some(ShaderGroup::TrianglesHit { .. }),
                                GeometryKind::Triangles
                            ) | (Some(ShaderGroup::ProceduralHit { .. }), GeometryKind::Aabbs)
                        );
                        if !ok {
                            push(fail(
                                format!("hit record {index}"),
                                format!("group {g} is not a {kind:?} hit group"),
                            ));
                        }
                    }
                }
            }
            Predicate::ClusterStructuresAllowed => {
                let Some(pl) = world.bound_pipeline() else {
                    return;
                };
                if !pl.allow_cluster_acceleration_structures && world.launch.cluster_structures {
                    push(fail("world.launch.cluster_structures", "the scene holds a cluster acceleration structure but the pipeline does not allow them"));
                }
            }
            Predicate::DynamicStackSizeSet => {
                if world.bound_pipeline().is_some_and(|p| p.dynamic_stack_size)
                    && !world.command_buffer.stack_size_set
                {
                    push(fail(
                        "commandBuffer",
                        "the pipeline's stack size is dynamic and was never set",
                    ));
                }
            }
            Predicate::NoStaticStateSet => {
                if world
                    .bound_pipeline()
                    .is_some_and(|p| !p.dynamic_stack_size)
                    && world.command_buffer.stack_size_set
                {
                    push(fail(
                        "commandBuffer",
                        "the stack size was set but the pipeline's is static",
                    ));
                }
            }
            Predicate::NoProtectedResourceFromUnprotected => {
                // (`protectedNoFault` devices drop this rule in `for_device`.)
                if world.command_buffer.protected {
                    return;
                }
                for p in cx.used_buffer_params() {
                    if let Some(b) = call.buffer_of(world, p) {
                        if b.flags.contains(crate::flags::BufferCreate::PROTECTED_BIT) {
                            push(fail(
                                call.param_path(p),
                                format!("buffer `{}` is protected", b.name),
                            ));
                        }
                    }
                }
            }
        }
    }
}

/// Whether the launch runs any invocation (dimensions known and none zero).
fn launches_anything(cx: &Context) -> bool {
    cx.call
        .dimensions(cx.world)
        .is_none_or(|d| d.iter().all(|&x| x > 0))
}

/// The (table, record index) pairs the launch reads (see [`crate::semantics::records_read`]).
pub fn reached_records(cx: &Context) -> Vec<(Table, u64)> {
    crate::semantics::records_read(cx.world, cx.call)
}

/// The hit records the launch reaches, with the kind of geometry each is reached from.
fn reached_hit_records(cx: &Context) -> Vec<(u64, GeometryKind)> {
    if !launches_anything(cx) {
        return vec![];
    }
    crate::semantics::reached_hit_records(cx.world, cx.call)
}
