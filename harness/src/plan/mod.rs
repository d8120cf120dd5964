//! The call plan of a case: every object the harness makes for it and every command it records, as
//! plain data — the device's extensions and features, buffers with their bytes, shader binding table
//! writes as group handles, the pipeline's stages and groups, the scene's geometry and instance
//! records, a build's memory images with the addresses they hold, the command buffer's steps and the
//! call. The ash executor realises it (`crate::execute`); `rtconf export` writes it as a standalone C
//! program; `rtconf replay` prints its steps. A case has one description of what runs.

pub mod build;
pub mod check;
pub mod device;
pub mod pipeline;
pub mod scene;
pub mod trace;

pub use crate::shaders::{ShaderBody, ShaderKind};
pub use build::BuildPlan;
pub use device::{DevicePlan, FeatureStruct};
pub use pipeline::{GroupPlan, PipelinePlan, StagePlan};
pub use scene::ScenePlan;
pub use trace::TracePlan;

use crate::error::HarnessError;
use crate::execute::Execution;
use model::case::Case;
use model::world::{CommandBufferLevel, PipelineApi};
use model::CommandId;

/// Refuses a primary command buffer stated executable or invalid inside a render pass instance
/// (trace and build plans alike): the harness makes those states by ending the command buffer (and
/// submitting it), a primary command buffer cannot end inside a render pass instance
/// (VUID-vkEndCommandBuffer-commandBuffer-00060), and ending the render pass first would leave the
/// call outside it.
pub(crate) fn refuse_ended_inside_render_pass(
    cbs: &model::world::CommandBufferState,
) -> Result<(), HarnessError> {
    use model::world::CommandBufferLifecycle as L;
    if cbs.level == CommandBufferLevel::Primary
        && cbs.in_render_pass
        && matches!(cbs.lifecycle, L::Executable | L::Invalid)
    {
        return Err(HarnessError::NotRealised(
            "a primary command buffer stated executable or invalid inside a render pass instance is not realised: the harness makes it so by ending it (and submitting it), and a primary command buffer cannot end inside a render pass instance (VUID-vkEndCommandBuffer-commandBuffer-00060); ending the render pass first would leave the call outside it".into(),
        ));
    }
    Ok(())
}

/// A case's plan: what the harness makes and records for it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CallPlan {
    pub case: String,
    pub command: CommandId,
    /// The call is run for real (a trace submitted and read back; a build built directly and traced).
    pub run_valid: bool,
    pub device: DevicePlan,
    pub body: PlanBody,
}

/// The plan of one command family.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[allow(clippy::large_enum_variant)] // one per case
pub enum PlanBody {
    Trace(TracePlan),
    Build(BuildPlan),
}

/// A memory dependency the harness records.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Barrier {
    /// From the scene's build (an earlier submission) to the ray tracing shaders' reads of it.
    SceneBuildToShaders,
    /// From the shaders' writes of the output to the host's read.
    ShaderWritesToHost,
}

/// One step of recording a case's command buffer and submitting it, in order.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum Step {
    /// Reset the command buffer of `level` (the recording target from here on) and leave it initial.
    Reset {
        level: CommandBufferLevel,
    },
    /// Begin it for one submission; a secondary one inherits nothing, or continues the empty render
    /// pass when `continue_render_pass`.
    Begin {
        level: CommandBufferLevel,
        continue_render_pass: bool,
    },
    Barrier(Barrier),
    /// The image layout transitions of the case's resource state (realised by `realise::resources`).
    ResourceTransitions,
    /// Bind the case's pipeline at the ray tracing bind point.
    BindPipeline,
    /// `vkCmdSetRayTracingPipelineStackSizeKHR` with the pipeline's default stack size (4096 when the
    /// spec's formula gives 0).
    SetStackSize,
    /// Bind the harness's descriptor set (scene, records, rays, callables, spheres) at set 0.
    BindHarnessSet,
    /// The descriptor sets and push constants of the case's resource state.
    ResourceBinds,
    /// Begin the empty 1x1 render pass, inline.
    BeginRenderPass,
    EndRenderPass,
    End,
    /// Submit once and wait, which makes a one-time-submit command buffer invalid (a secondary one
    /// is executed from the primary, inside the render pass when it continues one).
    SubmitToInvalidate,
    /// Record the case's call with the layer's messages collected; `dropped`: the messenger returns
    /// VK_TRUE, so the layer drops the call instead of passing it to the driver.
    Call {
        dropped: bool,
    },
    /// End the primary command buffer, submit it and wait.
    Submit,
    /// Read `words` output words back.
    ReadBack {
        words: usize,
    },
}

impl CallPlan {
    /// The plan of `case` run as `exec` says, or what the harness cannot realise (`Unsupported`).
    pub fn of(case: &Case, exec: &Execution) -> Result<CallPlan, HarnessError> {
        let (device, body) = match (&case.body, case.as_trace(), case.as_accel()) {
            (_, Some(t), _) => {
                let trace = TracePlan::of(t, exec.run_valid)?;
                let mut device =
                    DevicePlan::of(&t.world.device.extensions, &t.world.device.features);
                device.pool_family = trace.pool_family;
                (device, PlanBody::Trace(trace))
            }
            (_, _, Some(a)) => (
                DevicePlan::of(&a.world.device.extensions, &a.world.device.features),
                PlanBody::Build(BuildPlan::of(a)?),
            ),
            _ => return Err(HarnessError::Failed(format!("{}: no body", case.name))),
        };
        Ok(CallPlan {
            case: case.name.clone(),
            command: case.command(),
            run_valid: exec.run_valid,
            device,
            body,
        })
    }

    /// The call sequence as a person reads it, one line per object made or command recorded.
    pub fn describe(&self) -> Vec<String> {
        let mut out = vec![format!(
            "vkCreateDevice with {} and {}{}",
            if self.device.extensions.is_empty() {
                "no extensions".to_string()
            } else {
                self.device.extensions.join(", ")
            },
            if self.device.features.is_empty() {
                "no features".to_string()
            } else {
                self.device.features.join(", ")
            },
            match self.device.pool_family {
                Some(q) => format!(
                    "; a queue of the first family with compute and one of a family without compute with {}",
                    q.names().join(" | ")
                ),
                None => String::new(),
            }
        )];
        match &self.body {
            PlanBody::Trace(t) => t.describe(&mut out),
            PlanBody::Build(b) => b.describe(&mut out),
        }
        out
    }
}

/// The SPIR-V words of one of the harness's shaders for a pipeline API and body.
pub fn spirv(
    kind: ShaderKind,
    api: PipelineApi,
    body: ShaderBody,
) -> Result<Vec<u32>, HarnessError> {
    crate::shaders::spirv(kind, api, body)
}

/// A step as a person reads it.
pub fn step_text(step: &Step) -> String {
    let level = |l: &CommandBufferLevel| match l {
        CommandBufferLevel::Primary => "primary",
        CommandBufferLevel::Secondary => "secondary",
    };
    match step {
        Step::Reset { level: l } => format!("vkResetCommandBuffer ({})", level(l)),
        Step::Begin {
            level: l,
            continue_render_pass,
        } => format!(
            "vkBeginCommandBuffer ({}, ONE_TIME_SUBMIT{})",
            level(l),
            if *continue_render_pass {
                ", RENDER_PASS_CONTINUE in the empty render pass"
            } else {
                ""
            }
        ),
        Step::Barrier(Barrier::SceneBuildToShaders) => {
            "vkCmdPipelineBarrier (acceleration structure build writes → ray tracing shader reads)"
                .into()
        }
        Step::Barrier(Barrier::ShaderWritesToHost) => {
            "vkCmdPipelineBarrier (ray tracing shader writes → host reads)".into()
        }
        Step::ResourceTransitions => {
            "vkCmdPipelineBarrier (the resource state's image layouts)".into()
        }
        Step::BindPipeline => "vkCmdBindPipeline (RAY_TRACING_KHR, the case's pipeline)".into(),
        Step::SetStackSize => {
            "vkCmdSetRayTracingPipelineStackSizeKHR (the pipeline's default stack size)".into()
        }
        Step::BindHarnessSet => {
            "vkCmdBindDescriptorSets (set 0: scene, records, rays, callables, spheres)".into()
        }
        Step::ResourceBinds => {
            "vkCmdBindDescriptorSets / vkCmdPushConstants (the resource state)".into()
        }
        Step::BeginRenderPass => "vkCmdBeginRenderPass (the empty 1x1 render pass, inline)".into(),
        Step::EndRenderPass => "vkCmdEndRenderPass".into(),
        Step::End => "vkEndCommandBuffer".into(),
        Step::SubmitToInvalidate => {
            "vkQueueSubmit and wait (the one-time-submit buffer becomes invalid)".into()
        }
        Step::Call { dropped } => format!(
            "THE CALL, under the validation layer{}",
            if *dropped {
                " (the messenger returns VK_TRUE: the layer drops it)"
            } else {
                ""
            }
        ),
        Step::Submit => "vkEndCommandBuffer, vkQueueSubmit, vkWaitForFences".into(),
        Step::ReadBack { words } => format!("read {words} output words back"),
    }
}
