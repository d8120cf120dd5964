//! One-VUID mutations: each named [`Mutation`] takes a valid plan and breaks exactly one rule, boundary
//! values first (knob 0 is always the boundary: alignment + 1 byte, limit + 1, one byte past the end),
//! and says which co-violations the device makes unavoidable, decided from what the rules mean.
//!
//! [`mutations_for`] names the mutation of a VUID and [`supported`] says whether a profile can express
//! it; [`apply`] edits a plan (`apply.rs`).

mod apply;

pub use apply::apply;

use crate::mutation_io::{Mutated, MutationInput};
use crate::plan::{queue_families, realize, round_up, table_buffer, Plan, INDIRECT};
use crate::valid::GroupIndex;
use crate::GenError;
use model::flags::{BufferCreate, BufferUsage, PipelineCreate, QueueFlags};
use model::rules::RuleSet;
use model::world::{
    CommandBufferLifecycle, Contents, GeneralStage, GeometryKind, HandleRef, MemoryBinding,
    ShaderGroup,
};
use model::CommandId;
use model::{Call, DeviceProfile, Table, World};

/// Which NO_NULL_* hit flag a mutation breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NullHit {
    AnyHit,
    ClosestHit,
    Intersection,
}

/// A named way to break one rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mutation {
    /// Table address (KHR) or offset (NV) off the base alignment.
    MisalignTableAddress(Table),
    /// Table stride off the handle alignment (KHR) or handle size (NV).
    MisalignTableStride(Table),
    /// Table stride above `maxShaderGroupStride` (still aligned).
    TableStrideAboveMax(Table),
    /// Raygen region size different from its stride.
    RaygenSizeNotStride,
    /// The table's own buffer lacks SHADER_BINDING_TABLE usage.
    TableBufferUsage(Table),
    /// The table's own buffer is not bound to one memory object.
    TableBufferMemory(Table),
    IndirectBufferUsage,
    IndirectBufferMemory,
    MisalignIndirectAddress,
    /// The 12 bytes of the indirect command run past the end of its buffer.
    IndirectCommandPastEnd,
    /// A required feature is not enabled.
    DisableFeature(&'static str),
    /// ALLOW_MOTION pipeline without rayTracingMotionBlurPipelineTraceRaysIndirect.
    MotionPipelineWithoutFeature,
    /// A reached record holds a handle of another pipeline.
    ForeignHandle,
    /// Shader calls deeper than the pipeline's maximum recursion depth.
    RecursionTooDeep,
    /// NO_NULL_MISS pipeline with a zero handle (or no table) at the miss region's address.
    NullMissAtRegionAddress,
    NullHitReached(NullHit),
    /// NO_NULL_CLOSEST_HIT / NO_NULL_INTERSECTION pipeline with the hit table's address zero.
    NullHitTableWithNoNullFlag(NullHit),
    /// A reached hit record holds a group of the wrong kind for the geometry.
    HitGroupMismatch(GeometryKind),
    DynamicStackSizeNotSet,
    StaticStackSizeSet,
    ProtectedResource,
    ProtectedCommandBuffer,
    NotRecording,
    PoolWithoutCompute,
    InsideRenderPass,
    InsideVideoCoding,
    NoPipelineBound,
    /// No pipeline bound on a device with shaderObject enabled (08607 holds only there).
    NoPipelineBoundWithShaderObject,
    /// Launch dimension `i` above its limit.
    DimensionAboveLimit(u8),
    /// width × height × depth above maxRayDispatchInvocationCount.
    InvocationsAboveLimit,
    /// A region of non-zero size runs past the end of its buffer.
    RegionPastBufferEnd,
    /// A region's stride exceeds its buffer's size.
    StrideAboveBufferSize,
    /// NV: the table offset is not inside the buffer.
    NvOffsetPastBuffer(Table),
    /// NV: the table's buffer is not a valid handle.
    NvInvalidBuffer(Table),
    /// A resource-access rule broken in the world's resource state (`crate::resources`).
    Resource(crate::resources::ResourceMutation),
}

fn tables_by_tag(tag: &str, tags: [&str; 4]) -> Option<Table> {
    tags.iter().position(|t| *t == tag).map(|i| Table::ALL[i])
}

/// Why no mutation targets an executable trace VUID, if the generator says why.
pub fn unmutated(vuid: &str) -> Option<&'static str> {
    let tag = vuid.rsplit('-').next()?;
    match tag {
        "10577" | "10578" | "10579" => Some(
            "cluster acceleration structures (VK_NV_cluster_acceleration_structure) are not realised: no captured device has them",
        ),
        _ => None,
    }
}

/// The mutation that violates `vuid`, if one is written.
pub fn mutations_for(vuid: &str) -> Option<Mutation> {
    // Resource-access rules have their own mutations.
    if let Some(m) = crate::resources::mutation_for(vuid) {
        return Some(Mutation::Resource(m));
    }
    let rest = vuid.strip_prefix("VUID-")?;
    let (scope, rest) = rest.split_once('-')?;
    let tag = rest.rsplit('-').next()?;
    let khr = matches!(scope, "vkCmdTraceRaysIndirectKHR" | "vkCmdTraceRaysKHR");
    let nv = scope == "vkCmdTraceRaysNV";
    let common = |tag: &str| -> Option<Mutation> {
        Some(match tag {
            // The same rules under their newer VUIDs (08606/08607: a pipeline is bound; 08608: no
            // dynamic state set that the pipeline has static; 09458: a dynamic stack size was set).
            "02700" | "08606" => Mutation::NoPipelineBound,
            "08607" => Mutation::NoPipelineBoundWithShaderObject,
            "02859" | "08608" => Mutation::StaticStackSizeSet,
            "02701" | "09458" => Mutation::DynamicStackSizeNotSet,
            "03429" => Mutation::ForeignHandle,
            "02707" => Mutation::ProtectedResource,
            "03635" | "04624" => Mutation::ProtectedCommandBuffer,
            "cmdpool" => Mutation::PoolWithoutCompute,
            "recording" => Mutation::NotRecording,
            "renderpass" => Mutation::InsideRenderPass,
            "videocoding" => Mutation::InsideVideoCoding,
            "03679" | "03625" => Mutation::RecursionTooDeep,
            _ => return None,
        })
    };
    match scope {
        "VkStridedDeviceAddressRegionKHR" => match tag {
            "04631" => Some(Mutation::RegionPastBufferEnd),
            "04632" => Some(Mutation::StrideAboveBufferSize),
            _ => None,
        },
        "VkTraceRaysIndirectCommandKHR" => match tag {
            "03638" => Some(Mutation::DimensionAboveLimit(0)),
            "03639" => Some(Mutation::DimensionAboveLimit(1)),
            "03640" => Some(Mutation::DimensionAboveLimit(2)),
            "03641" => Some(Mutation::InvocationsAboveLimit),
            _ => None,
        },
        _ if khr => common(tag).or_else(|| {
            if let Some(t) = tables_by_tag(tag, ["03682", "03685", "03689", "03693"]) {
                return Some(Mutation::MisalignTableAddress(t));
            }
            if let Some(t) = tables_by_tag(tag, ["03681", "03684", "03688", "03692"]) {
                return Some(Mutation::TableBufferUsage(t));
            }
            if let Some(t) = tables_by_tag(tag, ["03680", "03683", "03687", "03691"]) {
                return Some(Mutation::TableBufferMemory(t));
            }
            if let Some(t) = tables_by_tag(tag, ["", "03686", "03690", "03694"]) {
                return Some(Mutation::MisalignTableStride(t));
            }
            if let Some(t) = tables_by_tag(tag, ["", "04029", "04035", "04041"]) {
                return Some(Mutation::TableStrideAboveMax(t));
            }
            Some(match tag {
                "04023" => Mutation::RaygenSizeNotStride,
                "03632" => Mutation::IndirectBufferMemory,
                "03633" => Mutation::IndirectBufferUsage,
                "03634" => Mutation::MisalignIndirectAddress,
                "03636" => Mutation::IndirectCommandPastEnd,
                "03637" => Mutation::DisableFeature("rayTracingPipelineTraceRaysIndirect"),
                "04951" => Mutation::MotionPipelineWithoutFeature,
                "03511" => Mutation::NullMissAtRegionAddress,
                "03512" => Mutation::NullHitReached(NullHit::AnyHit),
                "03513" => Mutation::NullHitReached(NullHit::ClosestHit),
                "03514" => Mutation::NullHitReached(NullHit::Intersection),
                "03696" => Mutation::NullHitTableWithNoNullFlag(NullHit::ClosestHit),
                "03697" => Mutation::NullHitTableWithNoNullFlag(NullHit::Intersection),
                "04735" => Mutation::HitGroupMismatch(GeometryKind::Triangles),
                "04736" => Mutation::HitGroupMismatch(GeometryKind::Aabbs),
                // vkCmdTraceRaysKHR's own dimension rules share the indirect structure's tags.
                "03638" if scope == "vkCmdTraceRaysKHR" => Mutation::DimensionAboveLimit(0),
                "03639" if scope == "vkCmdTraceRaysKHR" => Mutation::DimensionAboveLimit(1),
                "03640" if scope == "vkCmdTraceRaysKHR" => Mutation::DimensionAboveLimit(2),
                "03641" if scope == "vkCmdTraceRaysKHR" => Mutation::InvocationsAboveLimit,
                _ => return None,
            })
        }),
        _ if nv => common(tag).or_else(|| {
            if let Some(t) = tables_by_tag(tag, ["02455", "02457", "02459", "02461"]) {
                return Some(Mutation::NvOffsetPastBuffer(t));
            }
            if let Some(t) = tables_by_tag(tag, ["02456", "02458", "02460", "02462"]) {
                return Some(Mutation::MisalignTableAddress(t));
            }
            if let Some(t) = tables_by_tag(tag, ["", "02463", "02464", "02465"]) {
                return Some(Mutation::MisalignTableStride(t));
            }
            if let Some(t) = tables_by_tag(tag, ["", "02466", "02467", "02468"]) {
                return Some(Mutation::TableStrideAboveMax(t));
            }
            if let Some(t) = tables_by_tag(tag, ["04042", "04043", "04044", "04045"]) {
                return Some(Mutation::TableBufferMemory(t));
            }
            if tag == "parameter" {
                let field = rest.strip_suffix("-parameter")?;
                let t = Table::ALL
                    .into_iter()
                    .find(|t| field == format!("{}TableBuffer", t.nv_stem()))?;
                return Some(Mutation::NvInvalidBuffer(t));
            }
            Some(match tag {
                "02469" => Mutation::DimensionAboveLimit(0),
                "02470" => Mutation::DimensionAboveLimit(1),
                "02471" => Mutation::DimensionAboveLimit(2),
                _ => return None,
            })
        }),
        _ => None,
    }
}

/// Whether a mutation edits the pipeline description itself (its flags, groups, recursion depth or
/// stack-size state). Such a mutation starts from the drawn pipeline, so its pipelines are as varied as
/// the draws and the edit make them; every other mutation starts from a canonical pipeline
/// ([`crate::valid::canonical_base`]), since its rule is not about the pipeline and a pipeline a case
/// does not need to be new is a compile the driver need not do. A resource mutation templates the
/// stages' modules, not the description, so it takes the canonical description too.
pub fn edits_pipeline(m: Mutation) -> bool {
    matches!(
        m,
        Mutation::MotionPipelineWithoutFeature
            | Mutation::RecursionTooDeep
            | Mutation::NullMissAtRegionAddress
            | Mutation::NullHitReached(_)
            | Mutation::NullHitTableWithNoNullFlag(_)
            | Mutation::HitGroupMismatch(_)
            | Mutation::DynamicStackSizeNotSet
            | Mutation::StaticStackSizeSet
    )
}

/// Whether a mutation can be expressed on a profile (without building a case).
pub fn supported(m: Mutation, profile: &DeviceProfile, command: CommandId) -> Result<(), GenError> {
    let unsupported = |why: &str| {
        Err(GenError::Unsupported(format!(
            "{m:?} on {}: {why}",
            profile.name
        )))
    };
    let families = queue_families(profile);
    match m {
        // Resource mutations decide for themselves.
        Mutation::Resource(r) => crate::resources::supported(r, profile),
        Mutation::MotionPipelineWithoutFeature
            if !profile.has_extension("VK_NV_ray_tracing_motion_blur") =>
        {
            unsupported("no VK_NV_ray_tracing_motion_blur")
        }
        Mutation::NoPipelineBoundWithShaderObject if !profile.has_feature("shaderObject") => {
            unsupported("shaderObject is not supported, and 08607 holds only with it enabled")
        }
        Mutation::ProtectedResource | Mutation::ProtectedCommandBuffer
            if !profile.has_feature("protectedMemory") =>
        {
            unsupported("protectedMemory is not supported")
        }
        Mutation::ProtectedResource
            if profile.has_feature("protectedNoFault")
                || profile.limit("protectedNoFault") == Some(1) =>
        {
            unsupported("protectedNoFault is supported, so protected resources are allowed")
        }
        Mutation::ProtectedCommandBuffer
            if !families
                .iter()
                .any(|q| q.contains(QueueFlags::PROTECTED_BIT)) =>
        {
            unsupported("no queue family supports protected submissions")
        }
        Mutation::PoolWithoutCompute
            if !families
                .iter()
                .any(|q| !q.is_empty_set() && !q.contains(QueueFlags::COMPUTE_BIT)) =>
        {
            unsupported("every queue family supports compute")
        }
        Mutation::InsideVideoCoding
            if !families.iter().any(|q| {
                q.intersects(QueueFlags::VIDEO_DECODE_BIT_KHR | QueueFlags::VIDEO_ENCODE_BIT_KHR)
            }) =>
        {
            unsupported("no queue family supports video coding")
        }
        Mutation::InsideRenderPass
            if !families
                .iter()
                .any(|q| q.contains(QueueFlags::GRAPHICS_BIT | QueueFlags::COMPUTE_BIT)) =>
        {
            unsupported("no queue family supports graphics and compute")
        }
        _ => {
            let _ = command;
            Ok(())
        }
    }
}

trait EmptySet {
    fn is_empty_set(&self) -> bool;
}
impl EmptySet for QueueFlags {
    fn is_empty_set(&self) -> bool {
        self.0 == 0
    }
}
