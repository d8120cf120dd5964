//! A ray tracing pipeline's plan: one stage per shader a group uses (the harness's module of that kind,
//! specialised by constant 0 to the group's index and by constant 1 to its hit group's any-hit rule)
//! and the groups naming their stages, the flags, recursion depth and dynamic state — what
//! `realise::pipeline` creates and the C export writes.

use super::{ShaderBody, ShaderKind};
use crate::error::HarnessError;
use ash::vk;
use model::world::{GeneralStage, Pipeline, PipelineApi, ShaderGroup};

/// The create flags a `vkCreateRayTracingPipelinesNV` pipeline keeps of the case's: the KHR-only ones
/// (NO_NULL_*, SKIP_*, LIBRARY) are not NV pipeline flags; a descriptor buffer pipeline's
/// DESCRIPTOR_BUFFER_BIT_EXT is one.
pub const NV_PIPELINE_FLAGS: vk::PipelineCreateFlags = vk::PipelineCreateFlags::from_raw(
    vk::PipelineCreateFlags::DISABLE_OPTIMIZATION.as_raw()
        | vk::PipelineCreateFlags::DEFER_COMPILE_NV.as_raw()
        | vk::PipelineCreateFlags::DESCRIPTOR_BUFFER_EXT.as_raw(),
);
/// `VK_SHADER_UNUSED_KHR`.
pub const SHADER_UNUSED: u32 = vk::SHADER_UNUSED_KHR;

/// One shader stage of the pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct StagePlan {
    pub shader: ShaderKind,
    /// `VkShaderStageFlagBits`.
    pub stage: u32,
    /// The value of specialisation constant 0: the index of the group the stage serves.
    pub group: u32,
    /// The value of specialisation constant 1: the any-hit rule of its hit group
    /// (`model::tracer::AnyHitRule::code`; only the any-hit shader declares it; 0 for general groups).
    pub any_hit_rule: u32,
}

/// `VkRayTracingShaderGroupTypeKHR`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum GroupType {
    General,
    TrianglesHit,
    ProceduralHit,
}

impl GroupType {
    pub fn raw(self) -> i32 {
        match self {
            GroupType::General => vk::RayTracingShaderGroupTypeKHR::GENERAL.as_raw(),
            GroupType::TrianglesHit => {
                vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP.as_raw()
            }
            GroupType::ProceduralHit => {
                vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP.as_raw()
            }
        }
    }
}

/// One shader group: its type and the stages it names ([`SHADER_UNUSED`] for none).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct GroupPlan {
    pub ty: GroupType,
    pub general: u32,
    pub closest_hit: u32,
    pub any_hit: u32,
    pub intersection: u32,
}

/// The pipeline of a case.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct PipelinePlan {
    pub api: PipelineApi,
    /// `VkPipelineCreateFlags` as the case has them (an NV pipeline keeps the NV ones).
    pub flags: u32,
    pub max_recursion_depth: u32,
    pub dynamic_stack_size: bool,
    /// Created with VK_PIPELINE_CREATE_LIBRARY_KHR: it has no group handles of its own and takes the
    /// library interface below.
    pub library: bool,
    pub stages: Vec<StagePlan>,
    pub groups: Vec<GroupPlan>,
    /// The body of every stage's module: the full one, or the interface-only one of a case that is
    /// never submitted.
    pub body: ShaderBody,
}

/// The library interface of a pipeline library: the payload is twelve words (see
/// `shaders/raygen.rgen`); the hit attribute is a vec2.
pub const MAX_PAYLOAD_SIZE: u32 = 48;
pub const MAX_HIT_ATTRIBUTE_SIZE: u32 = 8;

impl PipelinePlan {
    /// The plan of a pipeline description; `trace` picks the raygen and closest-hit that trace into the
    /// scene, `body` the modules' bodies. A procedural group without an intersection shader is
    /// unsupported (no valid pipeline has one).
    pub fn of(p: &Pipeline, trace: bool, body: ShaderBody) -> Result<PipelinePlan, HarnessError> {
        let (raygen, closest) = if trace {
            (ShaderKind::RaygenTrace, ShaderKind::ClosestHitTrace)
        } else {
            (ShaderKind::RaygenPlain, ShaderKind::ClosestHitPlain)
        };
        let mut stages: Vec<StagePlan> = Vec::new();
        let mut groups = Vec::with_capacity(p.groups.len());
        for (g, group) in p.groups.iter().enumerate() {
            let g = g as u32;
            let any_hit_rule = match group {
                ShaderGroup::TrianglesHit { any_hit_rule, .. }
                | ShaderGroup::ProceduralHit { any_hit_rule, .. } => any_hit_rule.code(),
                ShaderGroup::General { .. } => 0,
            };
            let mut add = |shader: ShaderKind, stage: vk::ShaderStageFlags| -> u32 {
                stages.push(StagePlan {
                    shader,
                    stage: stage.as_raw(),
                    group: g,
                    any_hit_rule,
                });
                stages.len() as u32 - 1
            };
            let plan = match group {
                ShaderGroup::General { stage } => {
                    let (kind, flag) = match stage {
                        GeneralStage::Raygen => (raygen, vk::ShaderStageFlags::RAYGEN_KHR),
                        GeneralStage::Miss => (ShaderKind::Miss, vk::ShaderStageFlags::MISS_KHR),
                        GeneralStage::Callable => {
                            (ShaderKind::Callable, vk::ShaderStageFlags::CALLABLE_KHR)
                        }
                    };
                    GroupPlan {
                        ty: GroupType::General,
                        general: add(kind, flag),
                        closest_hit: SHADER_UNUSED,
                        any_hit: SHADER_UNUSED,
                        intersection: SHADER_UNUSED,
                    }
                }
                ShaderGroup::TrianglesHit {
                    closest_hit,
                    any_hit,
                    ..
                }
                | ShaderGroup::ProceduralHit {
                    closest_hit,
                    any_hit,
                    ..
                } => {
                    let ch = if *closest_hit {
                        add(closest, vk::ShaderStageFlags::CLOSEST_HIT_KHR)
                    } else {
                        SHADER_UNUSED
                    };
                    let ah = if *any_hit {
                        add(ShaderKind::AnyHit, vk::ShaderStageFlags::ANY_HIT_KHR)
                    } else {
                        SHADER_UNUSED
                    };
                    let (ty, is) = match group {
                        ShaderGroup::ProceduralHit {
                            intersection: true, ..
                        } => (
                            GroupType::ProceduralHit,
                            add(
                                ShaderKind::Intersection,
                                vk::ShaderStageFlags::INTERSECTION_KHR,
                            ),
                        ),
                        ShaderGroup::ProceduralHit { .. } => {
                            return Err(HarnessError::NotRealised(format!(
                                "group {g} is procedural without an intersection shader, which no valid pipeline has"
                            )))
                        }
                        _ => (GroupType::TrianglesHit, SHADER_UNUSED),
                    };
                    GroupPlan {
                        ty,
                        general: SHADER_UNUSED,
                        closest_hit: ch,
                        any_hit: ah,
                        intersection: is,
                    }
                }
            };
            groups.push(plan);
        }
        let flags = vk::PipelineCreateFlags::from_raw(p.flags.0 as u32);
        let flags = match p.api {
            PipelineApi::Nv => flags & NV_PIPELINE_FLAGS,
            PipelineApi::Khr => flags,
        };
        Ok(PipelinePlan {
            api: p.api,
            flags: flags.as_raw(),
            max_recursion_depth: p.max_recursion_depth,
            dynamic_stack_size: p.dynamic_stack_size && p.api == PipelineApi::Khr,
            library: p.api == PipelineApi::Khr
                && flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR),
            stages,
            groups,
            body,
        })
    }
}
