//! One-shot command buffers: a pool (of the compute family, or of a case's family without compute) with a
//! primary and a secondary buffer, a fence, begin / barrier / submit-and-wait, and an empty render pass
//! for calls recorded inside one.

use crate::error::{vkfail, HarnessError};
use crate::vk::VkDevice;
use ash::vk;

pub(crate) struct Commands {
    pub(crate) pool: vk::CommandPool,
    pub(crate) cb: vk::CommandBuffer,
    /// A secondary command buffer of the same pool, for cases recorded at the secondary level.
    pub(crate) secondary: vk::CommandBuffer,
    pub(crate) fence: vk::Fence,
    /// An empty render pass and its 1x1 framebuffer, made for cases recorded inside a render pass.
    pub(crate) render_pass: Option<(vk::RenderPass, vk::Framebuffer)>,
}

impl Commands {
    /// The compute family's pool, whose buffers the harness submits.
    pub(crate) fn new(dev: &VkDevice) -> Result<Commands, HarnessError> {
        Commands::of_family(dev, dev.queue_family)
    }

    /// A pool of `family`, one the device was created with a queue of. Only the compute family's
    /// buffers are submitted ([`Commands::submit_and_wait`] uses the device's compute queue).
    pub(crate) fn of_family(dev: &VkDevice, family: u32) -> Result<Commands, HarnessError> {
        let d = &dev.device;
        // SAFETY: valid create infos.
        unsafe {
            let pool = d
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .map_err(vkfail("vkCreateCommandPool"))?;
            let alloc = |level| {
                d.allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .level(level)
                        .command_buffer_count(1),
                )
                .map(|v| v[0])
                .map_err(vkfail("vkAllocateCommandBuffers"))
            };
            let cb = alloc(vk::CommandBufferLevel::PRIMARY)?;
            let secondary = alloc(vk::CommandBufferLevel::SECONDARY)?;
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .map_err(vkfail("vkCreateFence"))?;
            Ok(Commands {
                pool,
                cb,
                secondary,
                fence,
                render_pass: None,
            })
        }
    }
    pub(crate) fn begin(&self, dev: &VkDevice) -> Result<(), HarnessError> {
        // SAFETY: the command buffer is idle.
        unsafe {
            dev.device
                .reset_command_buffer(self.cb, vk::CommandBufferResetFlags::empty())
                .map_err(vkfail("vkResetCommandBuffer"))?;
            dev.device
                .begin_command_buffer(self.cb, &vk::CommandBufferBeginInfo::default())
                .map_err(vkfail("vkBeginCommandBuffer"))
        }
    }
    pub(crate) fn submit(&self, dev: &VkDevice) -> Result<(), HarnessError> {
        let d = &dev.device;
        // SAFETY: recorded command buffer, unsignalled fence.
        unsafe {
            d.end_command_buffer(self.cb)
                .map_err(vkfail("vkEndCommandBuffer"))?;
        }
        self.submit_and_wait(dev, self.cb)
    }
    /// Submits the ended command buffer `cb` on the fence and waits for it (a minute at most).
    pub(crate) fn submit_and_wait(
        &self,
        dev: &VkDevice,
        cb: vk::CommandBuffer,
    ) -> Result<(), HarnessError> {
        let d = &dev.device;
        // SAFETY: `cb` is executable; the fence is unsignalled.
        unsafe {
            let cbs = [cb];
            d.queue_submit(
                dev.queue,
                &[vk::SubmitInfo::default().command_buffers(&cbs)],
                self.fence,
            )
            .map_err(vkfail("vkQueueSubmit"))?;
            d.wait_for_fences(&[self.fence], true, 60_000_000_000)
                .map_err(vkfail("vkWaitForFences"))?;
            d.reset_fences(&[self.fence])
                .map_err(vkfail("vkResetFences"))
        }
    }
    /// Submits `cb` once and waits: a command buffer begun with ONE_TIME_SUBMIT and ended moves to
    /// the invalid state when that submission completes (spec, "Command Buffer Lifecycle"). A
    /// secondary one is executed once from this pool's primary, inside `render_pass` (continuing it)
    /// where one is given.
    pub(crate) fn submit_to_invalidate(
        &self,
        dev: &VkDevice,
        cb: vk::CommandBuffer,
        secondary: bool,
        render_pass: Option<(vk::RenderPass, vk::Framebuffer)>,
    ) -> Result<(), HarnessError> {
        let d = &dev.device;
        let submitted = if secondary {
            // SAFETY: the primary is idle (every submission of this pool is waited for); `cb` is an
            // executable secondary of the same pool, and the render pass objects are live.
            unsafe {
                d.reset_command_buffer(self.cb, vk::CommandBufferResetFlags::empty())
                    .map_err(vkfail("vkResetCommandBuffer"))?;
                d.begin_command_buffer(
                    self.cb,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .map_err(vkfail("vkBeginCommandBuffer"))?;
                if let Some(pass) = render_pass {
                    begin_render_pass(
                        d,
                        self.cb,
                        pass,
                        vk::SubpassContents::SECONDARY_COMMAND_BUFFERS,
                    );
                    d.cmd_execute_commands(self.cb, &[cb]);
                    d.cmd_end_render_pass(self.cb);
                } else {
                    d.cmd_execute_commands(self.cb, &[cb]);
                }
                d.end_command_buffer(self.cb)
                    .map_err(vkfail("vkEndCommandBuffer"))?;
            }
            self.cb
        } else {
            cb
        };
        self.submit_and_wait(dev, submitted)
    }

    /// Makes a build's writes visible to later builds and to the shaders that trace the result: the
    /// compute stage only when rayQuery is enabled (acceleration structure reads from other shader
    /// stages need it, VUID-vkCmdPipelineBarrier-dstAccessMask-06257), the ray tracing stage with
    /// ray tracing pipelines.
    pub(crate) fn barrier(&self, dev: &VkDevice) {
        let mut dst = vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR;
        if dev.has_feature("rayQuery") {
            dst |= vk::PipelineStageFlags::COMPUTE_SHADER;
        }
        if dev.has_feature("rayTracingPipeline") {
            dst |= vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR;
        }
        // SAFETY: recording.
        unsafe {
            memory_barrier(
                &dev.device,
                self.cb,
                (
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR,
                ),
                (
                    dst,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR | vk::AccessFlags::SHADER_READ,
                ),
            )
        };
    }
    /// The empty render pass (no attachments, one graphics subpass) and a 1x1 framebuffer for it.
    pub(crate) fn render_pass(
        &mut self,
        dev: &VkDevice,
    ) -> Result<(vk::RenderPass, vk::Framebuffer), HarnessError> {
        if let Some(rp) = self.render_pass {
            return Ok(rp);
        }
        let d = &dev.device;
        let subpass =
            [vk::SubpassDescription::default()
                .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)];
        // SAFETY: valid create infos; destroyed with the commands.
        unsafe {
            let rp = d
                .create_render_pass(
                    &vk::RenderPassCreateInfo::default().subpasses(&subpass),
                    None,
                )
                .map_err(vkfail("vkCreateRenderPass"))?;
            let fb = d
                .create_framebuffer(
                    &vk::FramebufferCreateInfo::default()
                        .render_pass(rp)
                        .width(1)
                        .height(1)
                        .layers(1),
                    None,
                )
                .map_err(|r| {
                    d.destroy_render_pass(rp, None);
                    vkfail("vkCreateFramebuffer")(r)
                })?;
            self.render_pass = Some((rp, fb));
            Ok((rp, fb))
        }
    }
    pub(crate) fn destroy(&self, dev: &VkDevice) {
        // SAFETY: idle.
        unsafe {
            if let Some((rp, fb)) = self.render_pass {
                dev.device.destroy_framebuffer(fb, None);
                dev.device.destroy_render_pass(rp, None);
            }
            dev.device.destroy_fence(self.fence, None);
            dev.device.destroy_command_pool(self.pool, None);
        }
    }
}

/// Records a global memory barrier from `src` (stages, accesses) to `dst`.
///
/// # Safety
/// `cb` is recording, outside a render pass instance.
pub(crate) unsafe fn memory_barrier(
    d: &ash::Device,
    cb: vk::CommandBuffer,
    src: (vk::PipelineStageFlags, vk::AccessFlags),
    dst: (vk::PipelineStageFlags, vk::AccessFlags),
) {
    let barrier = vk::MemoryBarrier::default()
        .src_access_mask(src.1)
        .dst_access_mask(dst.1);
    // SAFETY: guaranteed by the caller.
    unsafe {
        d.cmd_pipeline_barrier(
            cb,
            src.0,
            dst.0,
            vk::DependencyFlags::empty(),
            &[barrier],
            &[],
            &[],
        )
    };
}

/// Begins the 1x1 empty render pass `(pass, framebuffer)` in `cb`.
///
/// # Safety
/// `cb` is a recording primary command buffer outside a render pass instance; the objects are live.
pub(crate) unsafe fn begin_render_pass(
    d: &ash::Device,
    cb: vk::CommandBuffer,
    (pass, framebuffer): (vk::RenderPass, vk::Framebuffer),
    contents: vk::SubpassContents,
) {
    let info = vk::RenderPassBeginInfo::default()
        .render_pass(pass)
        .framebuffer(framebuffer)
        .render_area(vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: vk::Extent2D {
                width: 1,
                height: 1,
            },
        });
    // SAFETY: guaranteed by the caller.
    unsafe { d.cmd_begin_render_pass(cb, &info, contents) };
}

/// Resets `cb` and begins it for one submission.
///
/// # Safety
/// `cb` is not pending execution.
pub(crate) unsafe fn begin_one_time(
    d: &ash::Device,
    cb: vk::CommandBuffer,
) -> Result<(), HarnessError> {
    // SAFETY: guaranteed by the caller.
    unsafe {
        d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
            .map_err(vkfail("vkResetCommandBuffer"))?;
        d.begin_command_buffer(
            cb,
            &vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
        )
        .map_err(vkfail("vkBeginCommandBuffer"))
    }
}
